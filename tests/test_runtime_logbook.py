"""The logbook: line format and runtime time, levels, isolation, whole rows, kills, no key."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import logging
import subprocess
import sys
from functools import cache
from pathlib import Path
from typing import cast

import pytest

from clark_engine.link.codec import Codec
from clark_engine.link.fleet import FleetTable
from clark_engine.link.messages import AgentType, Heartbeat
from clark_engine.link.packet import Packet
from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.logbook import (
    MESSAGE_LOG_COLUMNS,
    Logbook,
    LogbookError,
    LogStreams,
)

ROOT = Path(__file__).resolve().parent.parent
GPS_MS = 1_700_000_000_000


@cache
def _configs() -> dict[str, str]:
    path = ROOT / "missions" / "cooperative_follow.yaml"
    result = validate_path(path, path.name)
    assert result.mission is not None
    return compile_mission(result.mission)


def config(agent: str = "mcs", level: str | None = None) -> AgentConfig:
    cfg = config_from_dict(json.loads(_configs()[agent]))
    return cfg if level is None else dataclasses.replace(cfg, log_level=level)


def text(stream: object) -> str:
    return cast(io.StringIO, stream).getvalue()


def lines(stream: object) -> list[str]:
    return text(stream).splitlines()


def log_a_tick(logbook: Logbook) -> None:
    logbook.set_time(12.3, GPS_MS + 45)
    logbook.mission.info("entered state %s", "survey", extra=LogEvent.BEHAVIOR_CHANGE.extra)


def warn_through_a_helper(logbook: Logbook) -> None:
    logbook.interface.warning("radio quiet", extra=LogEvent.RADIO_LINK.extra)


def the_caller(logbook: Logbook) -> None:
    warn_through_a_helper(logbook)


# ------------------------------------------------------------------ lines


def test_line_has_runtime_time_gps_level_and_event() -> None:
    logbook = Logbook.in_memory(config())
    log_a_tick(logbook)
    assert lines(logbook.streams.mission)[-1] == (
        f"t=12.300 gps_ms={GPS_MS + 45} INFO behavior.change: entered state survey"
    )


def test_a_line_names_its_event_not_the_code_that_logged_it() -> None:
    """Moving or renaming the logging function changes no byte (docs/logs.md)."""
    logbook = Logbook.in_memory(config())
    log_a_tick(logbook)

    def renamed_elsewhere(book: Logbook) -> None:
        book.mission.info("entered state %s", "survey", extra=LogEvent.BEHAVIOR_CHANGE.extra)

    renamed_elsewhere(logbook)
    first, second = lines(logbook.streams.mission)[-2:]
    assert first == second


def test_a_call_without_an_event_says_undeclared() -> None:
    logbook = Logbook.in_memory(config())
    logbook.mission.info("no event")
    assert lines(logbook.streams.mission)[-1] == "t=0.000 gps_ms=- INFO undeclared: no event"


def test_gps_time_unknown_is_a_dash() -> None:
    logbook = Logbook.in_memory(config())
    logbook.set_time(0.05, None)
    the_caller(logbook)
    assert lines(logbook.streams.interface)[-1] == (
        "t=0.050 gps_ms=- WARNING radio.link: radio quiet"
    )


def test_header_line_comes_first_whatever_the_level() -> None:
    logbook = Logbook.in_memory(config(level="ERROR"))
    log_a_tick(logbook)  # INFO: below ERROR
    for stream in (logbook.streams.mission, logbook.streams.interface):
        (only,) = lines(stream)
        assert only.startswith("t=0.000 gps_ms=- INFO log.open: logbook opened: ")
        assert "mission=cooperative-follow mission_id=521 agent=mcs agent_id=1" in only
        assert " loop_hz=10.0 period_s=0.1 level=ERROR" in only


@pytest.mark.parametrize(
    ("level", "shown"),
    [
        ("DEBUG", ["DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"]),
        ("INFO", ["INFO", "WARNING", "ERROR", "CRITICAL"]),
        ("WARNING", ["WARNING", "ERROR", "CRITICAL"]),
        ("ERROR", ["ERROR", "CRITICAL"]),
        ("CRITICAL", ["CRITICAL"]),
    ],
)
def test_level_comes_from_the_config(level: str, shown: list[str]) -> None:
    logbook = Logbook.in_memory(config(level=level))
    for name in ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"):
        logbook.mission.log(logging.getLevelNamesMapping()[name], "at %s", name)
    written = [line.split()[2] for line in lines(logbook.streams.mission)[1:]]
    assert written == shown


def test_a_level_change_takes_effect_at_once() -> None:
    logbook = Logbook.in_memory(config(level="INFO"))
    logbook.mission.debug("hidden")
    logbook.mission.setLevel(logging.DEBUG)
    logbook.mission.debug("shown")
    assert [line.rsplit(": ", 1)[1] for line in lines(logbook.streams.mission)[1:]] == ["shown"]


def test_loggers_are_private_and_never_reach_the_root() -> None:
    seen: list[logging.LogRecord] = []

    class Catch(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            seen.append(record)

    catch = Catch()
    logging.getLogger().addHandler(catch)
    try:
        logbook = Logbook.in_memory(config())
        logbook.mission.critical("mission")
        logbook.interface.critical("interface")
    finally:
        logging.getLogger().removeHandler(catch)
    assert seen == []
    assert logbook.mission.name == "clark.cooperative-follow.mcs.mission"
    assert logbook.interface.name == "clark.cooperative-follow.mcs.interface"
    assert not logbook.mission.propagate and not logbook.interface.propagate
    registered = logging.root.manager.loggerDict
    assert logbook.mission.name not in registered
    assert logbook.interface.name not in registered


def test_two_agents_in_one_process_do_not_mix() -> None:
    mcs, rover = Logbook.in_memory(config("mcs")), Logbook.in_memory(config("slash_a"))
    for i in range(3):
        mcs.set_time(i * 0.1, None)
        rover.set_time(100 + i * 0.1, GPS_MS + i)
        mcs.mission.info("mcs %d", i)
        rover.mission.info("slash_a %d", i)
        rover.interface.info("slash_a radio %d", i)
        mcs.message("sent", i * 0.1, None, "*", i + 1, 30, "heartbeat", 0)
    assert [line.split(": ")[-1] for line in lines(mcs.streams.mission)[1:]] == [
        "mcs 0",
        "mcs 1",
        "mcs 2",
    ]
    assert all(line.startswith("t=10") for line in lines(rover.streams.mission)[1:])
    assert "mcs" not in text(rover.streams.interface).split("agent=slash_a")[1]
    assert lines(rover.streams.messages) == [",".join(MESSAGE_LOG_COLUMNS)]
    assert len(lines(mcs.streams.messages)) == 4


def test_same_agent_twice_in_one_process_shares_nothing() -> None:
    first = Logbook.in_memory(config())
    second = Logbook.in_memory(config())
    first.mission.info("first")
    second.mission.info("second")
    first.close()
    second.mission.info("still second")
    assert "second" not in text(first.streams.mission)
    assert text(second.streams.mission).count("second") == 2


def test_same_inputs_same_bytes(tmp_path: Path) -> None:
    def run(folder: Path) -> dict[str, bytes]:
        with Logbook.to_folder(folder, config()) as logbook:
            for i in range(20):
                logbook.set_time(i / 10, GPS_MS + 100 * i)
                logbook.mission.info("tick %d", i)
                logbook.interface.debug("radio %d", i)
                logbook.message("sent", i / 10, GPS_MS + 100 * i, "*", i + 1, 31, "heartbeat", 0)
                logbook.fleet_row(i / 10, ["a", "b"], [[i, "x"]])
        return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}

    first = run(tmp_path / "one")
    assert first == run(tmp_path / "two")
    assert sorted(first) == [
        "mcs.fleet.csv",
        "mcs.interface.log",
        "mcs.messages.csv",
        "mcs.mission.log",
    ]


def test_the_key_never_reaches_the_logs() -> None:
    key = bytes(range(0x40, 0x60))
    codec = Codec(521, 1, key)
    logbook = Logbook.in_memory(config(level="DEBUG"))
    logbook.mission.debug("codec %r", codec)
    logbook.interface.info("codec %s", codec)
    logbook.message("rejected", 0.0, None, "slash_a", 3, 40, detail=repr(codec))
    logbook.close()
    written = "".join(text(s) for s in logbook.streams.all())
    assert "Codec(mission_id=521, agent_id=1, authenticated=True" in written
    for form in (key.hex(), key.hex().upper(), repr(key), key.decode("latin-1")):
        assert form not in written


# ------------------------------------------------------------------- CSVs


def test_message_rows_have_every_column_and_blanks_for_unknowns() -> None:
    logbook = Logbook.in_memory(config())
    logbook.message("sent", 0.5, GPS_MS, "*", 7, 52, "heartbeat", GPS_MS)
    logbook.message(
        "received", 0.625, GPS_MS + 140, "slash_a", 9, 60, "agent_status", GPS_MS + 20, 120.0
    )
    logbook.message("received", 0.7, None, "#12", 1, 60, "picture_data", GPS_MS)
    logbook.message("rejected", 0.75, None, "", None, 3, detail="MalformedPacket: short\nline")
    rows = list(csv.reader(io.StringIO(text(logbook.streams.messages))))
    assert rows == [
        list(MESSAGE_LOG_COLUMNS),
        ["sent", "0.5", str(GPS_MS), "*", "7", "52", "heartbeat", str(GPS_MS), "", ""],
        [
            "received",
            "0.625",
            str(GPS_MS + 140),
            "slash_a",
            "9",
            "60",
            "agent_status",
            str(GPS_MS + 20),
            "120.0",
            "",
        ],
        ["received", "0.7", "", "#12", "1", "60", "picture_data", str(GPS_MS), "", ""],
        ["rejected", "0.75", "", "", "", "3", "", "", "", "MalformedPacket: short\\x0aline"],
    ]
    assert text(logbook.streams.messages).count("\n") == 5  # one line per row


def test_message_refuses_what_would_make_a_bad_row() -> None:
    logbook = Logbook.in_memory(config())
    with pytest.raises(ValueError, match="direction"):
        logbook.message("lost", 0.0, None, "a", 1, 1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="finite"):
        logbook.message("received", 0.0, None, "a", 1, 1, "heartbeat", 1, float("nan"))
    assert lines(logbook.streams.messages) == [",".join(MESSAGE_LOG_COLUMNS)]


def test_a_fleet_cell_never_breaks_a_line() -> None:
    """Line breaks and control characters are escaped; delimiters and quotes are quoted."""
    logbook = Logbook.in_memory(config())
    rows: list[list[str | int]] = [
        [1, "two\nlines"],
        [2, "cr\rhere"],
        [3, "plain"],
        [4, 'a,"b"'],
        [5, "esc\x1b[2J"],
    ]
    logbook.fleet_row(0.5, ["a", "b"], rows)
    written = text(logbook.streams.fleet)
    assert written == (
        "now_s,a,b\n0.5,1,two\\x0alines\n0.5,2,cr\\x0dhere\n0.5,3,plain\n"
        '0.5,4,"a,""b"""\n0.5,5,esc\\x1b[2J\n'
    )


def test_text_log_arguments_are_escaped_and_bounded() -> None:
    """Whatever a caller logs, each record is one line without control characters."""
    logbook = Logbook.in_memory(config())
    logbook.mission.warning("terminate from %s: %s", "mcs", "bye\nt=1.000 forged\x1b" + "y" * 900)
    logbook.mission.warning("formatted by the caller: bye\r\nt=2.000 forged")
    logged = lines(logbook.streams.mission)[1:]
    assert len(logged) == 2 and all(line.startswith("t=") for line in logged)
    assert "\x1b" not in text(logbook.streams.mission)
    assert "y" * 600 not in logged[0] and logged[0].endswith("...")
    assert "bye\\x0dt=2.000" not in logged[1] and "\\x0d\\x0at=2.000" in logged[1]


def test_fleet_rows_from_the_fleet_table() -> None:
    table = FleetTable(1, 521, 3.0, {2: "slash_a"})
    beat = Heartbeat(agent_id=2, gps_time_ms=GPS_MS, mission_id=521, agent_type=AgentType.VEHICLE)
    table.receive(Packet(521, 2, 0, 1, False, (beat,), 40), 1.0, GPS_MS + 30)
    logbook = Logbook.in_memory(config())
    logbook.fleet_row(0.9, FleetTable.csv_header(), [])  # header even before any agent
    for now_s in (1.0, 1.1):
        logbook.fleet_row(now_s, FleetTable.csv_header(), table.csv_rows(now_s))
    rows = list(csv.DictReader(io.StringIO(text(logbook.streams.fleet))))
    assert list(rows[0]) == ["now_s", *FleetTable.csv_header()]
    assert [(r["now_s"], r["name"], r["latency_mean_ms"]) for r in rows] == [
        ("1.0", "slash_a", "30.0"),
        ("1.1", "slash_a", "30.0"),
    ]
    assert text(logbook.streams.fleet).count("now_s") == 1


def test_fleet_header_cannot_change_and_rows_must_fit() -> None:
    logbook = Logbook.in_memory(config())
    logbook.fleet_row(0.0, ["a", "b"], [[1, 2]])
    with pytest.raises(ValueError, match="header changed"):
        logbook.fleet_row(0.1, ["a", "c"], [[1, 2]])
    with pytest.raises(ValueError, match="3 cells for 2 columns"):
        logbook.fleet_row(0.1, ["a", "b"], [[1, 2, 3]])
    assert lines(logbook.streams.fleet) == ["now_s,a,b", "0.0,1,2"]


def test_rows_are_on_disk_before_the_writer_closes(tmp_path: Path) -> None:
    with Logbook.to_folder(tmp_path, config()) as logbook:
        logbook.set_time(0.1, None)
        logbook.mission.info("one")
        logbook.message("sent", 0.1, None, "*", 1, 30, "heartbeat", 0)
        logbook.fleet_row(0.1, ["a"], [[1]])
        assert (tmp_path / "mcs.messages.csv").read_text().splitlines()[1].startswith("sent,0.1,")
        assert (tmp_path / "mcs.fleet.csv").read_text() == "now_s,a\n0.1,1\n"
        assert (tmp_path / "mcs.mission.log").read_text().endswith(": one\n")
        assert not logbook.closed


_CHILD = """
import os, signal, sys
from pathlib import Path
from clark_engine.runtime.config import load_config
from clark_engine.runtime.logbook import Logbook
from clark_engine.link.fleet import FleetTable

config_path, folder, rows, how = sys.argv[1:]
logbook = Logbook.to_folder(Path(folder), load_config(Path(config_path)))
header = FleetTable.csv_header()
if how == "timer":  # killed after some CPU time, wherever it is then
    signal.signal(signal.SIGPROF, lambda *_: os.kill(os.getpid(), signal.SIGKILL))
    signal.setitimer(signal.ITIMER_PROF, 0.05)
i = 0
while how == "timer" or i < int(rows):
    now_s = i / 10
    logbook.set_time(now_s, 1_700_000_000_000 + 100 * i)
    logbook.mission.info("tick %d", i)
    logbook.message("received", now_s, 1_700_000_000_000 + 100 * i, "slash_a", i + 1, 57,
                    "agent_status", 1_700_000_000_000 + 100 * i - 40, 40.0, "detail, quoted")
    logbook.fleet_row(now_s, header, [[i] * len(header), [-i] * len(header)])
    i += 1
if how == "kill":
    os.kill(os.getpid(), signal.SIGKILL)
os._exit(0)  # no close, no flush at exit
"""


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL and setitimer are POSIX")
@pytest.mark.parametrize("how", ["kill", "exit", "timer"])
def test_a_killed_process_leaves_only_whole_rows(tmp_path: Path, how: str) -> None:
    config_path = tmp_path / "mcs.json"
    config_path.write_text(_configs()["mcs"])
    folder = tmp_path / "logs"
    rows = 250
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, str(config_path), str(folder), str(rows), how],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == (0 if how == "exit" else -9), done.stderr
    messages = (folder / "mcs.messages.csv").read_text()
    fleet = (folder / "mcs.fleet.csv").read_text()
    mission = (folder / "mcs.mission.log").read_text()
    for written in (messages, fleet, mission):
        assert written.endswith("\n")
    parsed = list(csv.reader(io.StringIO(messages)))
    assert parsed[0] == list(MESSAGE_LOG_COLUMNS)
    assert all(len(row) == len(MESSAGE_LOG_COLUMNS) for row in parsed)
    counters = [int(row[4]) for row in parsed[1:]]
    assert counters == list(range(1, len(counters) + 1))
    assert all(row[9] == "detail, quoted" for row in parsed[1:])
    width = len(FleetTable.csv_header()) + 1
    fleet_rows = list(csv.reader(io.StringIO(fleet)))
    assert all(len(row) == width for row in fleet_rows)
    ticks = [line.rsplit(" ", 1)[1] for line in mission.splitlines()[1:]]
    assert ticks == [str(i) for i in range(len(ticks))]
    if how == "timer":
        assert len(counters) >= 1
    else:
        assert len(counters) == rows
        assert len(fleet_rows) == 1 + 2 * rows
        assert len(ticks) == rows


# ------------------------------------------------------- opening, closing


def test_close_flushes_closes_and_is_idempotent(tmp_path: Path) -> None:
    logbook = Logbook.to_folder(tmp_path, config())
    logbook.close()
    logbook.close()
    assert logbook.closed
    assert all(stream.closed for stream in logbook.streams.all())
    with pytest.raises(ValueError, match="closed"):
        logbook.message("sent", 0.0, None, "*", 1, 1, "heartbeat")
    assert (tmp_path / "mcs.messages.csv").read_text() == ",".join(MESSAGE_LOG_COLUMNS) + "\n"


def test_a_line_after_close_is_dropped_quietly(capsys: pytest.CaptureFixture[str]) -> None:
    logbook = Logbook.in_memory(config())
    logbook.close()
    logbook.mission.critical("too late")
    assert "too late" not in text(logbook.streams.mission)
    assert capsys.readouterr().err == ""


def test_in_memory_streams_stay_readable_after_close() -> None:
    logbook = Logbook.in_memory(config())
    logbook.mission.warning("kept")
    logbook.close()
    assert "kept" in text(logbook.streams.mission)


def test_an_earlier_run_is_never_overwritten_by_default(tmp_path: Path) -> None:
    earlier = tmp_path / "mcs.fleet.csv"
    earlier.write_text("flight data\n")
    with pytest.raises(LogbookError, match="exists, from an earlier run") as caught:
        Logbook.to_folder(tmp_path, config())
    assert caught.value.file == str(earlier)
    assert earlier.read_text() == "flight data\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mcs.fleet.csv"]  # nothing left
    Logbook.to_folder(tmp_path, config(), overwrite=True).close()
    assert earlier.read_text() == ""


def test_bad_folder_or_file_names_are_reported(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(LogbookError, match="cannot create the log folder"):
        Logbook.to_folder(blocker / "logs", config())
    files = dict(config().log_files, fleet_csv="../escape.csv")
    with pytest.raises(LogbookError, match="not a plain file name"):
        Logbook.to_folder(tmp_path / "logs", dataclasses.replace(config(), log_files=files))
    assert not (tmp_path / "logs").exists()


class _FullDisk(io.StringIO):
    def write(self, s: str) -> int:
        raise OSError(28, "No space left on device")


def test_write_failures_are_counted_not_raised() -> None:
    streams = LogStreams(io.StringIO(), _FullDisk(), io.StringIO(), _FullDisk())
    logbook = Logbook(config(), streams)  # the message log header and one header line fail
    assert logbook.write_errors == 2
    logbook.interface.warning("lost line")
    assert logbook.write_errors == 3
    assert logbook.last_write_error == (
        "clark.cooperative-follow.mcs.interface: [Errno 28] No space left on device"
    )
    logbook.message("sent", 0.0, None, "*", 1, 1, "heartbeat")
    assert logbook.write_errors == 4
    assert logbook.last_write_error == "stream: No space left on device"
    logbook.mission.warning("kept line")
    assert logbook.write_errors == 4
    assert "kept line" in text(streams.mission)
