"""The simulated autopilot's parameters: ArduPilot's whole list, and the ones it acts on.

A ground station that downloads an ArduPilot vehicle's parameters gets its whole list
(1,200 to 1,400 names, in the order of ArduPilot's parameter tables), and reads and sets
any of them by name or index. The simulation acts on about 40 of them (the fence, the
failsafes, stream rates, speeds...). Both are kept here:

- **The list** comes from ArduPilot SITL itself (``tools/gen_sitl_params.py`` downloads
  it from each SITL build of ``../shared/ardupilot-sitl`` booted as the dry run boots it,
  into ``sitl_params/<firmware>.csv.gz``): names, MAVLink types, values, index order.
  It is read the first time a vehicle of that firmware is built and shared, read-only,
  by every vehicle of the process (:func:`sitl_table`), so that a fleet of 50 costs one
  load, and a vehicle only stores the values set on it.
- **The parameters the simulation acts on** (:class:`Param`, from ``sim/ardupilot/firmware.py``)
  keep their own value and type. Where SITL's default-parameter file gives another
  value (SITL's copter.parm sets FENCE_RADIUS 150 where the firmware's default is 300),
  **the simulated firmware's value wins**: it is what the simulation flies by and what a
  real vehicle, which has no SITL parameter file, starts with. A profile's
  ``parameters`` override both.

Values are stored as ArduPilot's AP_Param::set_float stores them: a float as a 32-bit
float; an integer with 0.01 added away from zero, clamped to its C type and truncated.
"""

from __future__ import annotations

import functools
import gzip
import math
import struct
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

DATA_DIR: Final = Path(__file__).resolve().parent / "sitl_params"
"""Where the generated lists live (package data, shipped in the wheel)."""

HEADER: Final = "name,type,value"
"""The first line of every list file."""

INT8, INT16, INT32, REAL32 = (
    int(mavlink2.MAV_PARAM_TYPE_INT8),
    int(mavlink2.MAV_PARAM_TYPE_INT16),
    int(mavlink2.MAV_PARAM_TYPE_INT32),
    int(mavlink2.MAV_PARAM_TYPE_REAL32),
)
INT_RANGES: Final[Mapping[int, tuple[int, int]]] = {
    INT8: (-128, 127),
    INT16: (-32768, 32767),
    INT32: (-(2**31), 2**31 - 1),
}
"""The C range of each integer parameter type (a set value is clamped to it)."""

_TYPES: Final = frozenset({*INT_RANGES, REAL32})
_FLOAT32_MAX: Final = 3.4028234663852886e38
NAME_BYTES: Final = 16
"""PARAM_VALUE.param_id's length: no ArduPilot parameter name is longer."""


def float32(value: float) -> float:
    """``value`` as a C float holds it (rounded to 24 bits; beyond the range, the largest)."""
    bounded = min(max(value, -_FLOAT32_MAX), _FLOAT32_MAX)
    return float(struct.unpack("<f", struct.pack("<f", bounded))[0])


def stored(value: float, param_type: int) -> float:
    """What AP_Param::set_float keeps of ``value`` for a parameter of ``param_type``.

    A float is kept as a 32-bit float; an integer gets 0.01 added away from zero, is
    clamped to its C type's range and truncated (2.7 -> 2, -2.7 -> -2, 300 in an int8 ->
    127). The documented @Range is never enforced. ``value`` must be finite.
    """
    single = float32(value)
    if param_type in INT_RANGES:
        low, high = INT_RANGES[param_type]
        nudged = float32(single + (0.01 if single >= 0 else -0.01))
        return float(math.trunc(min(max(nudged, low), high)))
    return single


@dataclass(slots=True)
class Param:
    """One parameter the simulation acts on: its value now and its MAVLink type."""

    value: float
    param_type: int


@dataclass(frozen=True, slots=True)
class SitlTable:
    """One firmware's whole parameter list as ArduPilot SITL reports it (read-only)."""

    firmware: str
    names: tuple[str, ...]
    """Every name in ArduPilot's index order (PARAM_VALUE.param_index)."""
    types: Mapping[str, int]
    """Name -> MAV_PARAM_TYPE."""
    values: Mapping[str, float]
    """Name -> the value SITL reports after booting with its default-parameter file."""
    index: Mapping[str, int]
    """Name -> its index."""


@functools.cache
def sitl_table(firmware: str) -> SitlTable:
    """``firmware``'s list, read from the package's data once per process and shared.

    Raises:
        OSError: The list file is missing (a broken install).
        ValueError: The file is not a list this module wrote, or names repeat.
    """
    path = DATA_DIR / f"{firmware}.csv.gz"
    lines = gzip.decompress(path.read_bytes()).decode("ascii").splitlines()
    if not lines or lines[0] != HEADER:
        raise ValueError(f"{path}: not a parameter list (first line {lines[:1]!r})")
    names: list[str] = []
    types: dict[str, int] = {}
    values: dict[str, float] = {}
    for number, line in enumerate(lines[1:], start=2):
        name, kind, value = line.split(",")
        if name in types or int(kind) not in _TYPES or not 0 < len(name) <= NAME_BYTES:
            raise ValueError(f"{path}:{number}: bad or repeated parameter {line!r}")
        names.append(name)
        types[name] = int(kind)
        values[name] = float(value)
    return SitlTable(
        firmware,
        tuple(names),
        types,
        values,
        {name: i for i, name in enumerate(names)},
    )


class ParamStore:
    """One vehicle's parameters: the whole list a station sees, over the acting ones.

    Args:
        firmware: ``arduplane``, ``arducopter`` or ``ardurover`` (its SITL list).
        acting: The parameters the simulation acts on, by name (kept by reference: the
            autopilot reads and writes them directly, on its hot paths).
    """

    def __init__(self, firmware: str, acting: dict[str, Param]) -> None:
        self.table = sitl_table(firmware)
        self.acting = acting
        self._set: dict[str, float] = {}  # values set on listed parameters it does not act on

    @property
    def count(self) -> int:
        """PARAM_VALUE.param_count: how many parameters the list has."""
        return len(self.table.names)

    def __contains__(self, name: object) -> bool:
        return name in self.acting or name in self.table.types

    def names(self) -> Iterator[str]:
        """Every listed name, in index order."""
        return iter(self.table.names)

    def name_at(self, index: int) -> str | None:
        """The name at ``index`` in the list, None beyond it."""
        names = self.table.names
        return names[index] if 0 <= index < len(names) else None

    def get(self, name: str) -> tuple[float, int] | None:
        """(value, MAV_PARAM_TYPE) of ``name``; None when the vehicle has no such parameter."""
        entry = self.acting.get(name)
        if entry is not None:
            return entry.value, entry.param_type
        kind = self.table.types.get(name)
        if kind is None:
            return None
        value = self._set.get(name)
        return (self.table.values[name] if value is None else value), kind

    def set(self, name: str, value: float) -> bool:
        """Store ``value`` (finite) as ArduPilot would; True when the simulation acts on it.

        Raises:
            KeyError: No such parameter.
        """
        entry = self.acting.get(name)
        if entry is not None:
            entry.value = stored(value, entry.param_type)
            return True
        self._set[name] = stored(value, self.table.types[name])
        return False
