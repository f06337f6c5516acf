"""clark_engine.sitl.launcher: finding SITL, choosing free instances, and never leaving a process.

Most tests run fake launchers (shell scripts in tmp_path that take the real one's
arguments), so they need no ArduPilot; the last ones, marked ``sitl``, run the real
builds in ../shared/ardupilot-sitl (or $CLARK_SITL) and skip without them.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import stat
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from sitl_here import real_install

from clark_engine.errors import ClarkError
from clark_engine.sitl.errors import SitlError, SitlNotFound
from clark_engine.sitl.instances import (
    ENV_SITL_INSTANCES,
    InstanceLock,
    InstancePorts,
    instance_free,
    parse_instances,
    port_free,
    reserve_instance,
)
from clark_engine.sitl.launcher import (
    ENV_SITL,
    Home,
    SitlInstall,
    SitlProcess,
    vehicle_for_firmware,
)

ROOT = Path(__file__).resolve().parent.parent
HOME = Home(30.6372, -96.4787, 90.0, 0.0)
# High instance numbers (ports 7260 and up): clear of the ones people start by hand; or
# the range this machine's user keeps to ($CLARK_SITL_INSTANCES).
INSTANCES = (
    parse_instances(os.environ[ENV_SITL_INSTANCES])
    if os.environ.get(ENV_SITL_INSTANCES)
    else range(150, 190)
)


def alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie waiting for its parent to reap it counts as gone)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def gone_within(pid: int, timeout_s: float) -> bool:
    """Polls (a process's death has no file descriptor to wait on): True once it is gone."""
    deadline = time.monotonic() + timeout_s
    while alive(pid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def make_launcher(folder: Path, body: str) -> Path:
    """A fake ``sitl`` launcher: ``$1`` vehicle, ``$2`` instance, ``$3`` home."""
    folder.mkdir(parents=True, exist_ok=True)
    launcher = folder / "sitl"
    launcher.write_text("#!/bin/sh\n" + textwrap.dedent(body))
    launcher.chmod(launcher.stat().st_mode | stat.S_IXUSR)
    return launcher


# A launcher that execs a process listening on the instance's MAVLink port, as SITL does.
LISTENER = f"""\
    echo "fake SITL $1 instance $2 home $3 speedup $CLARK_SITL_SPEEDUP work $CLARK_SITL_WORK"
    exec {sys.executable} -c '
import signal, socket, sys, time
s = socket.socket()
s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
s.bind(("0.0.0.0", 5760 + 10 * int(sys.argv[1])))
s.listen(1)
print("listening", flush=True)
while True:
    time.sleep(1)
' "$2"
"""


@pytest.fixture
def listener(tmp_path: Path) -> SitlInstall:
    return SitlInstall(make_launcher(tmp_path / "fake", LISTENER))


# -- finding the launcher ------------------------------------------------------------------


def test_find_takes_the_folder_given(tmp_path: Path) -> None:
    launcher = make_launcher(tmp_path / "sitl-folder", "exit 0\n")
    install = SitlInstall.find(str(tmp_path / "sitl-folder"), environ={})
    assert install.launcher == launcher.resolve()
    assert install.folder == launcher.parent.resolve()


def test_find_takes_the_launcher_itself(tmp_path: Path) -> None:
    launcher = make_launcher(tmp_path / "x", "exit 0\n")
    assert SitlInstall.find(str(launcher), environ={}).launcher == launcher.resolve()


def test_find_falls_back_to_the_environment(tmp_path: Path) -> None:
    launcher = make_launcher(tmp_path / "env", "exit 0\n")
    install = SitlInstall.find(None, environ={ENV_SITL: str(tmp_path / "env")})
    assert install.launcher == launcher.resolve()


def test_the_instances_come_from_the_option_then_the_environment(tmp_path: Path) -> None:
    """A shared lab machine keeps runs apart by instance ranges (--sitl-instances, or
    $CLARK_SITL_INSTANCES for every run and test of one user)."""
    make_launcher(tmp_path / "s", "exit 0\n")
    folder = str(tmp_path / "s")
    assert SitlInstall.find(folder, environ={}).instances == range(0, 100)
    env = {ENV_SITL_INSTANCES: "20-39"}
    assert SitlInstall.find(folder, environ=env).instances == range(20, 40)
    assert SitlInstall.find(folder, instances="7", environ=env).instances == range(7, 8)
    launcher = SitlInstall.find(folder, instances="200-201", environ={})
    process = SitlProcess(launcher, "rover", HOME)
    assert process._instances == [200, 201]


@pytest.mark.parametrize("text", ["39-20", "x", "-1-3", "20-", "1-99999", "250-256", "1" * 40])
def test_a_bad_instance_range_says_what_to_write(tmp_path: Path, text: str) -> None:
    make_launcher(tmp_path / "s", "exit 0\n")
    with pytest.raises(SitlError, match=r"FIRST-LAST, each 0\.\.255 \(ArduPilot's limit\)"):
        SitlInstall.find(str(tmp_path / "s"), instances=text, environ={})
    with pytest.raises(SitlError, match=r"\$CLARK_SITL_INSTANCES"):
        SitlInstall.find(str(tmp_path / "s"), environ={ENV_SITL_INSTANCES: text})


def test_the_cli_takes_an_instance_range_only_with_sitl(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from clark_engine.cli import main

    mission = str(ROOT / "missions" / "single_vehicle_mode_change.yaml")
    assert main(["dry-run", mission, "--sitl-instances", "20-39"]) == 2
    assert "--sitl-instances only applies with --autopilot sitl" in capsys.readouterr().err
    assert main(["autopilot-sim", mission, "--agent", "slash", "--sitl-instances", "1-2"]) == 2
    assert "--sitl-instances only applies with --autopilot sitl" in capsys.readouterr().err


def test_the_path_given_beats_the_environment(tmp_path: Path) -> None:
    given = make_launcher(tmp_path / "given", "exit 0\n")
    make_launcher(tmp_path / "env", "exit 0\n")
    install = SitlInstall.find(str(given.parent), environ={ENV_SITL: str(tmp_path / "env")})
    assert install.launcher == given.resolve()


def test_nothing_given_says_what_to_do() -> None:
    with pytest.raises(SitlNotFound) as caught:
        SitlInstall.find(None, environ={})
    assert isinstance(caught.value, ClarkError)
    assert str(caught.value) == (
        "no ArduPilot SITL given: pass --sitl PATH or set CLARK_SITL to the folder with "
        "the `sitl` launcher (e.g. ../shared/ardupilot-sitl)"
    )


@pytest.mark.parametrize("given", ["missing", "empty-folder"])
def test_a_path_without_a_launcher_is_not_found(tmp_path: Path, given: str) -> None:
    (tmp_path / "empty-folder").mkdir()
    with pytest.raises(
        SitlNotFound, match=r"--sitl .*(not found|has no `sitl` launcher).*CLARK_SITL"
    ):
        SitlInstall.find(str(tmp_path / given), environ={})


def test_the_environment_is_named_when_it_is_wrong(tmp_path: Path) -> None:
    with pytest.raises(SitlNotFound, match=r"^\$CLARK_SITL .*not found"):
        SitlInstall.find(None, environ={ENV_SITL: str(tmp_path / "nowhere")})


def test_a_launcher_that_cannot_run_is_refused(tmp_path: Path) -> None:
    (tmp_path / "sitl").write_text("#!/bin/sh\n")
    (tmp_path / "sitl").chmod(0o644)
    with pytest.raises(SitlNotFound, match="not executable"):
        SitlInstall.find(str(tmp_path), environ={})


# -- instances and their ports ---------------------------------------------------------------


def test_instance_ports_follow_ardupilot() -> None:
    ports = InstancePorts(3)
    assert ports.mavlink_tcp_port == 5790
    assert ports.tcp_ports == (5790, 5792, 5793)
    assert ports.rc_input_udp_port == 5531
    assert ports.udp_ports == (5531, 9035)


def test_home_is_the_launchers_argument() -> None:
    assert HOME.argument() == "30.6372000,-96.4787000,90,0"


def test_a_port_in_use_is_not_free() -> None:
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen(1)
        port = held.getsockname()[1]
        assert not port_free(port, socket.SOCK_STREAM)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("127.0.0.1", 0))
        assert not port_free(held.getsockname()[1], socket.SOCK_DGRAM)


def free_instances(count: int) -> list[int]:
    found = [i for i in INSTANCES if instance_free(i)][:count]
    if len(found) < count:
        pytest.skip(f"fewer than {count} free SITL instances in {INSTANCES}")
    return found


def test_a_busy_instance_is_skipped(tmp_path: Path) -> None:
    busy, free = free_instances(2)
    with socket.socket() as taken:  # someone else's SITL on the busy one's SERIAL2 port
        taken.bind(("127.0.0.1", InstancePorts(busy).tcp_ports[2]))
        taken.listen(1)
        lock = reserve_instance([busy, free], tmp_path)
    try:
        assert lock.instance == free
    finally:
        lock.release()


def test_a_locked_instance_is_skipped_even_in_one_process(tmp_path: Path) -> None:
    first, second = free_instances(2)
    held = InstanceLock.try_acquire(first, tmp_path)
    assert held is not None
    try:
        assert InstanceLock.try_acquire(first, tmp_path) is None
        lock = reserve_instance([first, second], tmp_path)
        assert lock.instance == second
        lock.release()
    finally:
        held.release()
    again = InstanceLock.try_acquire(first, tmp_path)
    assert again is not None
    again.release()


def test_no_free_instance_says_why(tmp_path: Path) -> None:
    (only,) = free_instances(1)
    held = InstanceLock.try_acquire(only, tmp_path)
    assert held is not None
    try:
        with pytest.raises(SitlError, match="no free SITL instance among"):
            reserve_instance([only], tmp_path)
    finally:
        held.release()


def test_processes_racing_for_instances_never_share(tmp_path: Path) -> None:
    candidates = free_instances(6)
    racer = textwrap.dedent(
        f"""
        import sys
        from pathlib import Path
        from clark_engine.sitl.instances import reserve_instance
        lock = reserve_instance({candidates!r}, Path({str(tmp_path)!r}))
        print(lock.instance, flush=True)
        sys.stdin.read()  # hold the lock until told to stop
        """
    )
    racers = [
        subprocess.Popen(
            [sys.executable, "-c", racer],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        for _ in range(4)
    ]
    try:
        chosen = [int(r.stdout.readline()) for r in racers]  # type: ignore[union-attr]
    finally:
        for r in racers:
            r.communicate("", timeout=30)
    assert len(set(chosen)) == 4, chosen
    assert all(r.returncode == 0 for r in racers)


# -- starting and stopping (fake launchers) ---------------------------------------------------


def test_start_waits_for_the_port_and_stop_ends_everything(listener: SitlInstall) -> None:
    process = SitlProcess(listener, "rover", HOME, speedup=7, instances=INSTANCES)
    with process:
        pid = process.pid
        assert pid is not None and alive(pid)
        assert not port_free(process.ports.mavlink_tcp_port, socket.SOCK_STREAM)
        work = process.work_dir
        log = process.log_path.read_text()
        assert f"fake SITL rover instance {process.instance} home {HOME.argument()}" in log
        assert f"speedup 7 work {work}" in log
        lock_path = process.lock_dir / f"instance-{process.instance}.lock"
        held = InstanceLock.try_acquire(process.instance, process.lock_dir)
        assert held is None, "the instance is not locked while SITL runs"
        sock = process.connect(timeout_s=5)
        sock.close()
    assert not alive(pid)
    assert not work.exists()
    assert lock_path.exists()
    again = InstanceLock.try_acquire(process.instance, process.lock_dir)
    assert again is not None
    again.release()
    process.stop()  # idempotent


def test_keep_work_keeps_the_folder(listener: SitlInstall) -> None:
    with SitlProcess(listener, "copter", HOME, instances=INSTANCES, keep_work=True) as process:
        work = process.work_dir
    try:
        assert (work / "sitl.log").exists()
    finally:
        for f in work.iterdir():
            f.unlink()
        work.rmdir()


def test_stop_kills_what_ignores_sigterm_and_the_whole_group(tmp_path: Path) -> None:
    # The launcher does not exec: it leaves a child behind, and both ignore SIGTERM.
    launcher = make_launcher(
        tmp_path / "stubborn",
        f"""\
        trap '' TERM
        sleep 1000 &
        echo $! > "$CLARK_SITL_WORK/child.pid"
        {LISTENER.strip().replace("exec ", "", 1)}
        """,
    )
    process = SitlProcess(
        SitlInstall(launcher), "plane", HOME, instances=INSTANCES, stop_grace_s=0.3, keep_work=True
    )
    with process:
        pid = process.pid
        assert pid is not None
        child = int((process.work_dir / "child.pid").read_text())
        assert alive(child)
    try:
        assert not alive(pid)
        assert gone_within(child, 5), "the launcher's child outlived stop()"
    finally:
        for f in process.work_dir.iterdir():
            f.unlink()
        process.work_dir.rmdir()


def test_a_sitl_that_exits_early_raises_with_its_log(tmp_path: Path) -> None:
    launcher = make_launcher(
        tmp_path / "broken", "echo 'Unknown parameter SIM_FOO'\necho 'giving up' >&2\nexit 1\n"
    )
    process = SitlProcess(SitlInstall(launcher), "rover", HOME, instances=INSTANCES)
    with pytest.raises(SitlError) as caught:
        process.start()
    message = str(caught.value)
    assert "exited before it listened" in message
    assert "[exit code 1]" in message
    assert "Unknown parameter SIM_FOO\ngiving up" in message
    assert not process.running
    lock = InstanceLock.try_acquire(process.instance, process.lock_dir)
    assert lock is not None, "the instance stays locked after a failed start"
    lock.release()


def test_a_sitl_that_never_listens_is_stopped(tmp_path: Path) -> None:
    launcher = make_launcher(tmp_path / "mute", "echo 'Waiting for ever'\nexec sleep 1000\n")
    process = SitlProcess(
        SitlInstall(launcher), "rover", HOME, instances=INSTANCES, start_timeout_s=0.5
    )
    with pytest.raises(
        SitlError, match=r"(?s)did not listen on TCP \d+ within 0.5 s.*Waiting for ever"
    ):
        process.start()
    assert process.pid is not None and not alive(process.pid)


def test_a_launcher_that_cannot_start_raises(tmp_path: Path) -> None:
    launcher = tmp_path / "sitl"
    launcher.write_text("not a script")
    launcher.chmod(0o755)
    with pytest.raises(SitlError, match="could not be started"):
        SitlProcess(SitlInstall(launcher), "rover", HOME, instances=INSTANCES).start()


def test_a_port_taken_behind_our_back_moves_to_the_next_instance(tmp_path: Path) -> None:
    # As SITL does when its bind fails: "bind failed on port ... Address already in use".
    # The first free instance, not the range's first: the suite's real SITL tests take
    # instances of the same range meanwhile (this test skipped when one held the first).
    first = next((i for i in INSTANCES if instance_free(i)), None)
    if first is None:
        pytest.skip(f"no free SITL instance in {INSTANCES}")
    launcher = make_launcher(
        tmp_path / "unlucky",
        f"""\
        if [ "$2" = "{first}" ]; then
          echo "bind failed on port $((5760 + 10 * $2)) - Address already in use"
          exit 1
        fi
        {LISTENER.strip()}
        """,
    )
    instances = range(first, INSTANCES.stop)
    with SitlProcess(SitlInstall(launcher), "rover", HOME, instances=instances) as process:
        assert process.instance > first


def test_wrong_arguments_are_refused(listener: SitlInstall) -> None:
    with pytest.raises(ValueError, match="unknown SITL vehicle 'boat'"):
        SitlProcess(listener, "boat", HOME)
    with pytest.raises(ValueError, match="speed-up"):
        SitlProcess(listener, "rover", HOME, speedup=0)
    process = SitlProcess(listener, "rover", HOME)
    with pytest.raises(SitlError, match="not running"):
        process.connect()


def test_rc_input_packets(listener: SitlInstall) -> None:
    with SitlProcess(listener, "rover", HOME, instances=INSTANCES) as process:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rc:
            try:
                rc.bind(("127.0.0.1", process.ports.rc_input_udp_port))
            except OSError:
                pytest.skip("the RC input port is taken")
            rc.settimeout(5)
            process.rc_input([1500, 1100, 1900])
            packet = rc.recv(100)
        assert len(packet) == 32  # 16 little-endian uint16; 0 leaves a channel as it was
        assert packet[:6] == bytes.fromhex("dc054c046c07") and set(packet[6:]) == {0}
        with pytest.raises(ValueError, match="1 to 16"):
            process.rc_input([1500] * 17)
        with pytest.raises(ValueError, match="channel 2: 70000 us"):
            process.rc_input([1500, 70000])


def run_child(code: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(code)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )


def test_interpreter_exit_stops_a_forgotten_sitl(listener: SitlInstall) -> None:
    child = run_child(
        f"""
        from pathlib import Path
        from clark_engine.sitl.launcher import Home, SitlInstall, SitlProcess
        p = SitlProcess(SitlInstall(Path({str(listener.launcher)!r})), "rover",
                        Home(30.0, -96.0, 90.0), instances=range(150, 190))
        p.start()
        print(p.pid, flush=True)
        """  # and exits without stop()
    )
    out, _ = child.communicate(timeout=60)
    pid = int(out.split()[0])
    assert child.returncode == 0
    assert not alive(pid)


def test_a_killed_parent_takes_its_sitl_along(listener: SitlInstall) -> None:
    child = run_child(
        f"""
        import sys
        from pathlib import Path
        from clark_engine.sitl.launcher import Home, SitlInstall, SitlProcess
        p = SitlProcess(SitlInstall(Path({str(listener.launcher)!r})), "rover",
                        Home(30.0, -96.0, 90.0), instances=range(150, 190))
        p.start()
        print(p.pid, p.work_dir, flush=True)
        sys.stdin.read()
        """
    )
    try:
        pid_text, work = child.stdout.readline().split()  # type: ignore[union-attr]
        pid = int(pid_text)
        assert alive(pid)
    finally:
        child.send_signal(signal.SIGKILL)  # no atexit, no finally: only the kernel helps
        child.communicate(timeout=30)
    assert gone_within(pid, 10), "SITL outlived the process that started it"
    shutil.rmtree(work)  # what a killed process cannot clean up


# -- real SITL ---------------------------------------------------------------------------------


REAL = real_install()
needs_sitl = pytest.mark.skipif(
    REAL is None,
    reason=f"no ArduPilot SITL: set {ENV_SITL} to the folder with the `sitl` launcher",
)


@pytest.fixture
def rover() -> Iterator[SitlProcess]:
    assert REAL is not None
    with SitlProcess(REAL, "rover", HOME, speedup=10) as process:
        yield process


def read_until(sock: socket.socket, want: str, where: object, timeout_s: float) -> object:
    """The first message of type ``want`` for which ``where(msg)`` holds (wall-clock bound)."""
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    sock.settimeout(1.0)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            data = sock.recv(65536)
        except TimeoutError:
            continue
        assert data, "SITL closed the connection"
        for msg in parser.parse_buffer(data) or []:
            if msg.get_type() == want and where(msg):  # type: ignore[operator]
                return msg
    raise AssertionError(f"no {want} matching within {timeout_s} s")


@pytest.mark.sitl
@needs_sitl
def test_real_sitl_binds_the_ports_we_check_and_leaves_nothing(rover: SitlProcess) -> None:
    sock = rover.connect(timeout_s=30)
    try:
        read_until(sock, "SYS_STATUS", lambda m: True, 30)  # running: every port is bound
        for port in rover.ports.tcp_ports:
            assert not port_free(port, socket.SOCK_STREAM), f"TCP {port}"
        assert not port_free(rover.ports.rc_input_udp_port, socket.SOCK_DGRAM)
    finally:
        sock.close()
    pid = rover.pid
    assert pid is not None
    rover.stop()
    assert not alive(pid)
    assert instance_free(rover.instance)


@pytest.mark.sitl
@needs_sitl
def test_real_sitl_rc_input_reaches_rc_channels(rover: SitlProcess) -> None:
    sock = rover.connect(timeout_s=30)
    mav = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    try:
        # SITL streams RC_CHANNELS at 1 Hz (ArduCopter not at all): ask for 10 Hz.
        sock.sendall(
            mav.command_long_encode(
                1,
                1,
                mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL,
                0,
                mavlink2.MAVLINK_MSG_ID_RC_CHANNELS,
                100_000,
                0,
                0,
                0,
                0,
                0,
            ).pack(mav)
        )
        read_until(sock, "RC_CHANNELS", lambda m: True, 30)  # its RC input port is bound
        rover.rc_input([1500, 1500, 1700, 1500, 1800, 1000, 1000, 1800, 1234])
        rc = read_until(sock, "RC_CHANNELS", lambda m: m.chan3_raw == 1700, 10)
        assert rc.chan9_raw == 1234  # type: ignore[attr-defined]
        rover.rc_input([0, 0, 1300])  # 0: unchanged
        rc = read_until(sock, "RC_CHANNELS", lambda m: m.chan3_raw == 1300, 10)
        assert rc.chan9_raw == 1234  # type: ignore[attr-defined]
    finally:
        sock.close()


@pytest.mark.sitl
@needs_sitl
def test_two_real_sitls_get_different_instances() -> None:
    assert REAL is not None
    with (
        SitlProcess(REAL, "rover", HOME, speedup=10) as one,
        SitlProcess(REAL, "plane", HOME, speedup=10) as two,
    ):
        assert one.instance != two.instance
        one.connect(timeout_s=30).close()
        two.connect(timeout_s=30).close()


def test_firmware_names_a_vehicle() -> None:
    assert [vehicle_for_firmware(f) for f in ("ardurover", "arducopter", "arduplane")] == [
        "rover",
        "copter",
        "plane",
    ]
    with pytest.raises(SitlError, match="no SITL vehicle runs firmware 'px4'"):
        vehicle_for_firmware("px4")


def test_a_fixed_instance_that_is_busy_is_refused(listener: SitlInstall) -> None:
    # Other test runs on this machine take free instances of the same range, lowest first:
    # the highest free one is the least likely to be taken by them between the port's
    # release and the start; if one still is, the claim is tried again on another.
    for _attempt in range(3):
        free = [i for i in reversed(INSTANCES) if instance_free(i)]
        if not free:
            pytest.skip(f"no free SITL instance in {INSTANCES}")
        busy = free[0]
        with socket.socket() as taken:
            taken.bind(("127.0.0.1", InstancePorts(busy).mavlink_tcp_port))
            taken.listen(1)
            process = SitlProcess(listener, "rover", HOME, instance=busy)
            with pytest.raises(SitlError, match=f"SITL instance {busy} is locked .* or one of its"):
                process.start()
        try:
            with SitlProcess(listener, "rover", HOME, instance=busy) as process:
                assert process.instance == busy
        except SitlError:
            if instance_free(busy):
                raise  # refused though nobody holds it: the fault is ours
            continue  # someone else's SITL took it the moment it was released
        return
    pytest.fail("every instance tried was taken by another process as soon as it was released")
