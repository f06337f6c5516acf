"""The terminal of ``clark run``: the live status, the station's operator commands, its script.

- :class:`StatusView`: one screen redrawn twice a second when stdout is a terminal
  (state, mode, armed, peers and their age, link statistics, overruns), or one plain
  line every few seconds otherwise (a log file, a service's journal).
- :class:`OperatorConsole`: the station's commands typed on its terminal, read
  without blocking from the shell's selector (no thread): ``activate AGENT|all``,
  ``deactivate AGENT|all``, ``mode AGENT MODE``, ``terminate`` (asks ``type yes``),
  ``help``. Each becomes a :class:`~clark_engine.runtime.events.StationCommand`.
- :class:`OperatorScript`: the mission's ``operator:`` entries played at their
  ``at_s`` after the loop starts (``--script``).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any, TextIO

from clark_engine.runtime.events import StationCommand
from clark_engine.shells.realtime import RealtimeShell

SCREEN_PERIOD_S = 0.5
"""How often the terminal screen is redrawn."""

LINE_PERIOD_S = 5.0
"""How often a plain status line is written when stdout is not a terminal."""

HELP = (
    "commands: activate AGENT|all, deactivate AGENT|all, mode AGENT MODE, "
    "terminate [AGENT|all], status, help"
)


def status_lines(shell: RealtimeShell, now_s: float) -> list[str]:
    """What the status shows, one string per line."""
    runtime = shell.runtime
    config = runtime.config
    machine = runtime.machine
    state = (", ".join(machine.active_paths()) if machine is not None else "") or "-"
    if runtime.terminated:
        state = "terminated"
    elif not runtime.behavior_started:
        state = "not started (waiting for launch)"
    lines = [
        f"{config.agent} ({config.role}) mission {config.mission_name}  t={now_s:7.1f} s  "
        f"state: {state}" + (f"  failsafe: {runtime.failsafe}" if runtime.failsafe else ""),
    ]
    link = shell.autopilot
    if link is not None:
        vehicle = runtime.context.vehicle
        up = "up" if link.transport is not None else f"down ({link.reopen.last_error})"
        if vehicle is not None:
            lines.append(
                f"autopilot {link.describe} {up}: mode {vehicle.mode} "
                f"{'ARMED' if vehicle.armed else 'disarmed'} "
                f"lat {vehicle.lat_deg:.6f} lon {vehicle.lon_deg:.6f} alt {vehicle.alt_m:.1f} m"
                + ("  LOST" if runtime.autopilot_lost else "")
            )
        else:
            waiting = ", ".join(link.adapter.status.waiting_for) or "-"
            lines.append(f"autopilot {link.describe} {up}: no state yet (waiting for {waiting})")
    elif config.is_vehicle:
        lines.append("autopilot: disabled (testing mode)")
    radio = shell.radio
    if radio is not None and radio.radio is not None:
        s = radio.radio.stats
        lines.append(
            f"radio {radio.radio.name}: sent {s.sent} received {s.received} "
            f"failures {sum(s.send_failures.values())} dropped {sum(s.dropped.values())}"
        )
    elif radio is not None:
        lines.append(f"radio {radio.describe}: down ({radio.reopen.last_error})")
    else:
        lines.append("radio: disabled (testing mode)")
    records = runtime.fleet.agents()
    if not records:
        lines.append("peers: none heard yet")
    for record in records:
        st = record.stats
        loss = st.loss_ratio
        lines.append(
            f"  {record.name:<12} {'LOST' if record.lost else 'ok  '} "
            f"heard {record.since_heartbeat_s(now_s):5.1f} s ago  packets {st.packets} "
            f"loss {'-' if loss is None else f'{loss:.0%}'}"
            + (f"  latency {st.latency_mean_ms:.0f} ms" if st.latency_mean_ms is not None else "")
        )
    s2 = shell.stats
    lines.append(
        f"loop {shell.loop_hz:g} Hz: {s2.ticks} ticks, {s2.overruns} overruns "
        f"({s2.skipped_ticks} skipped), max late {s2.max_late_s * 1000:.1f} ms, "
        f"longest tick {s2.max_tick_s * 1000:.1f} ms"
    )
    return lines


class StatusView:
    """Draws the status on a terminal, or writes a plain line now and then.

    Args:
        out: Where to write (stdout).
        screen: Redraw a screen (a terminal) rather than write lines.
    """

    def __init__(self, out: TextIO, *, screen: bool) -> None:
        self.out = out
        self.screen = screen
        self._next_s = 0.0
        self.messages: list[str] = []
        """The latest operator messages, shown under the screen."""

    def __call__(self, shell: RealtimeShell, now_s: float) -> None:
        """An on-tick hook: draw when due."""
        if now_s < self._next_s:
            return
        self._next_s = now_s + (SCREEN_PERIOD_S if self.screen else LINE_PERIOD_S)
        lines = status_lines(shell, now_s)
        try:
            if self.screen:
                text = "\x1b[H\x1b[J" + "\n".join(lines + self.messages[-5:]) + "\n> "
            else:
                text = " | ".join(line.strip() for line in lines) + "\n"
            self.out.write(text)
            self.out.flush()
        except (OSError, ValueError):
            pass  # a closed terminal must not stop the loop

    def say(self, text: str) -> None:
        """Show an operator message (printed at once when not a screen)."""
        self.messages.append(text)
        if not self.screen:
            try:
                self.out.write(text + "\n")
                self.out.flush()
            except (OSError, ValueError):
                pass


def parse_command(words: Sequence[str], agents: Sequence[str]) -> StationCommand | str:
    """One operator line's words as a command, or the reason it is not one."""
    if not words:
        return "empty line"
    verb = words[0].lower()

    def target(word: str) -> str | None:
        if word == "all":
            return ""
        return word if word in agents else None

    if verb in ("activate", "deactivate", "terminate") and len(words) <= 2:
        if len(words) == 1:
            if verb != "terminate":
                return f"usage: {verb} AGENT|all ({', '.join(agents)})"
            return StationCommand("terminate", "")
        name = target(words[1])
        if name is None:
            return f"no agent {words[1]!r}; agents: {', '.join(agents)}, all"
        return StationCommand(verb, name)
    if verb == "mode" and len(words) == 3:
        name = target(words[1])
        if name is None or name == "":
            return f"no agent {words[1]!r}; agents: {', '.join(agents)}"
        return StationCommand("mode", name, words[2].upper())
    return f"unknown command {' '.join(words)!r}; {HELP}"


class OperatorConsole:
    """The station's operator commands from a terminal, read without blocking.

    Args:
        shell: The station's shell.
        fd: The terminal's descriptor (stdin).
        view: Where answers are shown.
    """

    def __init__(self, shell: RealtimeShell, fd: int, view: StatusView) -> None:
        self.shell = shell
        self.fd = fd
        self.view = view
        self.agents = [p.name for p in shell.runtime.config.peers if p.role != "mcs"]
        self._buffer = b""
        self._pending: StationCommand | None = None
        os.set_blocking(fd, False)
        shell.add_reader(fd, self.readable)

    def readable(self, now_s: float) -> None:
        """Read what was typed and act on every complete line."""
        try:
            data = os.read(self.fd, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:  # end of input: stop reading, keep flying
            self.shell.remove_reader(self.fd)
            return
        self._buffer += data
        while b"\n" in self._buffer:
            raw, _, self._buffer = self._buffer.partition(b"\n")
            self.line(raw.decode("utf-8", "replace").strip(), now_s)
        if len(self._buffer) > 1024:
            self._buffer = b""

    def line(self, text: str, now_s: float) -> None:
        """Act on one typed line."""
        pending, self._pending = self._pending, None
        if pending is not None:
            if text == "yes":
                self.view.say(f"operator: terminate {pending.target or 'all'}: sent")
                self.shell.deliver(pending, now_s)
            else:
                self.view.say("operator: terminate cancelled")
            return
        words = text.split()
        if not words:
            return
        if words[0] in ("help", "?"):
            self.view.say(HELP)
            return
        if words[0] == "status":
            for status in status_lines(self.shell, now_s):
                self.view.say(status)
            return
        command = parse_command(words, self.agents)
        if isinstance(command, str):
            self.view.say(f"operator: {command}")
            return
        if command.action == "terminate":
            self._pending = command
            self.view.say(
                f"operator: terminate {command.target or 'every agent'}? type yes to confirm"
            )
            return
        self.view.say(f"operator: {' '.join(words)}: sent")
        self.shell.deliver(command, now_s)


class OperatorScript:
    """The mission's ``operator:`` entries played at their times (an on-tick hook).

    Only the station's entries are played (activate, deactivate, mode, terminate);
    a pilot's ``rc`` entries act on a vehicle's sticks, which a real run leaves to
    its pilot, and are skipped.
    """

    def __init__(self, entries: Sequence[Mapping[str, Any]], view: StatusView) -> None:
        self.view = view
        self._entries = sorted(
            (float(item["at_s"]), i, item) for i, item in enumerate(entries) if "rc" not in item
        )

    def __call__(self, shell: RealtimeShell, now_s: float) -> None:
        """Play every entry due."""
        start = shell.start_s or 0.0
        while self._entries and self._entries[0][0] <= now_s - start:
            at_s, _, item = self._entries.pop(0)
            for action in ("activate", "deactivate", "terminate"):
                if action in item:
                    target = "" if item[action] == "all" else str(item[action])
                    self.view.say(f"script at {at_s:g} s: {action} {item[action]}")
                    shell.deliver(StationCommand(action, target), now_s)
            if "mode" in item:
                body = item["mode"]
                self.view.say(f"script at {at_s:g} s: mode {body['agent']} {body['mode']}")
                shell.deliver(StationCommand("mode", str(body["agent"]), str(body["mode"])), now_s)
