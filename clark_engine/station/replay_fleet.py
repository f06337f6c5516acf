"""A fleet CSV read for the replay: each observed agent's rows as columns of numbers.

Separate from the replay because reading and indexing the logs is its own work, and the
largest: an hour of 100 agents is millions of rows, kept as :mod:`array` columns
(:class:`FleetRows`) that the replay (:mod:`clark_engine.station.replay_frames`) then
reads by index (:data:`LAT`, :data:`LON`... name the columns). Every cell is data from a
file: a row that cannot be read is a :class:`~clark_engine.analysis.latency.Problem` and
is skipped, texts are escaped and bounded, names too (:func:`shown_name`).
"""

from __future__ import annotations

import math
import operator
from array import array
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from clark_engine.analysis.latency import Problem
from clark_engine.analysis.log_folder import shown_name
from clark_engine.expectations.log_readers import fleet_csv
from clark_engine.runtime.log_lines import line_safe
from clark_engine.station.view_protocol import MAX_LOG_TEXT_CHARS
from clark_engine.untrusted import printable

MAX_AGENTS: Final = 256
"""Most agents a replay shows; the logs of more are ignored (with a warning)."""

MAX_FLEET_ROWS: Final = 5_000_000
"""Most rows read from one fleet CSV (an hour of 100 agents at 10 Hz is 3.6 million)."""

#: Fleet CSV columns kept per row, in this order (docs/logs.md, "The fleet CSV").
NUMBERS: Final = (
    "since_heartbeat_s",
    "lat_deg",
    "lon_deg",
    "alt_m",
    "ground_speed_m_s",
    "climb_rate_m_s",
    "heading_deg",
    "mode",
    "status_age_s",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "packets",
    "lost_packets",
    "loss_ratio",
    "latency_mean_ms",
    "bad_tags",
    "malformed",
    "duplicates",
    "armed",
    "battery_v",
    "battery_pct",
    "gps_fix_type",
    "satellites",
    "autopilot_severity",
    "autopilot_text_age_s",
    "autopilot_lost",
    "health_age_s",
)
#: Fleet CSV text columns kept per row (Vehicle Health's), interned.
TEXTS: Final = ("prearm", "autopilot_text", "failsafe")
PREARM, AP_TEXT, FAILSAFE = range(len(TEXTS))
MAX_TEXTS: Final = 10_000
"""Distinct Vehicle Health texts kept per fleet CSV; the rest read as a note saying so."""
_TOO_MANY_TEXTS: Final = "(more distinct texts than the replay keeps)"
_REQUIRED: Final = ("now_s", "name", "condition", "lost", "since_heartbeat_s")
CONDITIONS: Final = ("ok", "degraded", "failsafe", "terminated")
(
    SINCE_HB,
    LAT,
    LON,
    ALT,
    SPEED,
    CLIMB,
    HEADING,
    MODE,
    STATUS_AGE,
    ROLL,
    PITCH,
    YAW,
    PACKETS,
    LOST_PACKETS,
    LOSS_RATIO,
    LATENCY,
    BAD_TAGS,
    MALFORMED,
    DUPLICATES,
    ARMED,
    BATTERY_V,
    BATTERY_PCT,
    GPS_FIX,
    SATELLITES,
    AP_SEVERITY,
    AP_TEXT_AGE,
    AP_LOST,
    HEALTH_AGE,
) = range(len(NUMBERS))


@dataclass(slots=True)
class FleetRows:
    """One observer's fleet-table rows of one agent, as columns (its own clock)."""

    agent_id: int
    now_s: array[float] = field(default_factory=lambda: array("d"))
    numbers: list[array[float]] = field(default_factory=list)
    """One array per column of :data:`NUMBERS` (NaN for an empty cell), once read."""
    condition: array[int] = field(default_factory=lambda: array("b"))
    lost: array[int] = field(default_factory=lambda: array("b"))
    flat: array[float] = field(default_factory=lambda: array("d"))
    """While reading: every row's numbers one after the other (one append per row)."""
    texts: list[array[int]] = field(default_factory=lambda: [array("l") for _ in TEXTS])
    """One array per column of :data:`TEXTS`: each row's index in :attr:`strings`."""
    strings: list[str] = field(default_factory=lambda: [""])
    """The distinct texts of :attr:`texts`, escaped and bounded; index 0 is empty."""
    lookup: dict[str, int] = field(default_factory=dict)
    """A text as read -> its index in :attr:`strings` (while reading)."""

    def __len__(self) -> int:
        return len(self.now_s)

    def columns(self) -> None:
        """Turn the rows read (:attr:`flat`) into :attr:`numbers`' columns."""
        width = len(NUMBERS)
        self.numbers = [self.flat[c::width] for c in range(width)]
        self.flat = array("d")
        self.lookup = {}


def _bad_cell(row: list[str], columns: Sequence[tuple[str, int | None]]) -> str:
    """Which of ``columns`` in ``row`` is not a number, in words."""
    for column, index in columns:
        if index is None or row[index] == "":
            continue
        try:
            float(row[index])
        except ValueError:
            return f"{column} is {printable(row[index], 40)!r}, not a number"
    return "a value is not a number"


def read_fleet_columns(
    path: Path, names: Mapping[str, int] | None, problems: list[Problem]
) -> dict[str, FleetRows]:
    """Observed agent -> its rows in one agent's fleet CSV (docs/logs.md, "The fleet CSV").

    Args:
        path: The file.
        names: The mission's agents by name with their ids; rows of others are skipped.
            None takes every name (bounded and escaped).
        problems: Where rows and files that cannot be read go.

    Raises:
        UsageError: The file cannot be read.
    """
    shown = str(path)
    opened = fleet_csv(path, _REQUIRED, problems)
    if opened is None:
        return {}
    header, rows = opened
    width = len(header)
    at = {column: header.index(column) for column in header}
    now_at, name_at, id_at = at["now_s"], at["name"], at.get("agent_id")
    condition_at, lost_at = at["condition"], at["lost"]
    indexes = [at.get(column) for column in NUMBERS]
    text_at = [at.get(column) for column in TEXTS]
    labelled = list(zip(NUMBERS, indexes, strict=True))
    missing = None in indexes  # an older logbook's header: those columns are empty
    cells = operator.itemgetter(*(width if i is None else i for i in indexes))
    out: dict[str, FleetRows] = {}
    escaped: dict[str, str] = {}  # a name as written -> as shown (bounded, escaped)
    strangers: set[str] = set()
    nan = math.nan
    count = 0
    for number, row in rows:
        count += 1
        if count > MAX_FLEET_ROWS:
            problems.append(Problem(shown, number, f"more than {MAX_FLEET_ROWS} rows; the rest"))
            break
        if len(row) != width:
            problems.append(Problem(shown, number, f"expected {width} fields, found {len(row)}"))
            continue
        name = row[name_at]
        if names is None:
            name = escaped.get(name) or escaped.setdefault(name, shown_name(name))
        elif name not in names:
            strangers.add(name)
            continue
        if missing:
            row.append("")
        try:
            now_s = float(row[now_at])
            values = [float(cell) if cell else nan for cell in cells(row)]
        except ValueError:
            bad = _bad_cell(row, [("now_s", now_at), *labelled])
            problems.append(Problem(shown, number, bad))
            continue
        if not math.isfinite(now_s):
            problems.append(Problem(shown, number, f"now_s is {row[now_at]!r}, not finite"))
            continue
        condition = row[condition_at]
        if condition not in CONDITIONS and condition != "":
            what = printable(condition, 40)
            problems.append(Problem(shown, number, f"condition {what!r} is not a condition"))
            continue
        agent = out.get(name)
        if agent is None:
            if names is None:
                if not name or len(out) >= MAX_AGENTS:
                    continue
                try:
                    agent_id = int(row[id_at]) if id_at is not None else 0
                except ValueError:
                    agent_id = 0
            else:
                agent_id = names[name]
            agent = out[name] = FleetRows(agent_id)
        if len(agent.now_s) and now_s < agent.now_s[-1]:
            problems.append(Problem(shown, number, "now_s goes back in time"))
            continue
        agent.now_s.append(now_s)
        agent.flat.extend(values)
        for column, index in zip(agent.texts, text_at, strict=True):
            column.append(_intern(agent, row[index]) if index is not None and row[index] else 0)
        agent.condition.append(CONDITIONS.index(condition) if condition else -1)
        agent.lost.append(1 if row[lost_at] == "1" else 0)
    for agent in out.values():
        agent.columns()
    if strangers:
        problems.append(
            Problem(
                shown,
                None,
                "rows of agents not in the mission: "
                + ", ".join(sorted(printable(s, 40) for s in strangers)[:5]),
            )
        )
    return out


def _intern(rows: FleetRows, cell: str) -> int:
    """The index of a Vehicle Health text in ``rows.strings``, escaped and bounded.

    The texts came over the air and through a file: each is escaped (its CSV cell was
    already, by the logbook) and cut; at most :data:`MAX_TEXTS` distinct ones are kept.
    """
    index = rows.lookup.get(cell)
    if index is None:
        if len(rows.strings) > MAX_TEXTS:
            cell = _TOO_MANY_TEXTS
            index = rows.lookup.get(cell)
            if index is not None:
                return index
        index = len(rows.strings)
        rows.strings.append(line_safe(cell, MAX_LOG_TEXT_CHARS))
        rows.lookup[cell] = index
    return index


__all__ = [
    "MAX_AGENTS",
    "MAX_FLEET_ROWS",
    "MAX_TEXTS",
    "FleetRows",
    "read_fleet_columns",
]
