"""Varied values: what a mission leaves to chance, and one run's draw of it.

A dry run is one sample of a noisy world. A mission says how noisy by giving a value of
its ``sim:`` world (the wind, the GPS error, the radio's bursts...) or a fault's time
as a distribution instead of a number::

    sim:
      radio_loss: {uniform: [0.0, 0.1]}
      wind: {speed_mps: {normal: {mean: 4, sd: 1.5}}, from_deg: {uniform: [0, 360]}}
    faults:
      - kill: {agent: slash_a, at_s: {uniform: [40, 80]}, chance: 0.5}

Each run draws every such value once, from a generator seeded by the run's seed and the
value's path (``sim.wind.speed_mps``), so that declaring one more varied value does not
change the draws of the others, and so that a run is reproduced by its seed alone. A
fault with a ``chance`` is injected in that share of runs. ``clark dry-run --vary
PATH=VALUE`` fixes a value instead of drawing it (a number, or ``true``/``false`` for a
fault's ``injected``), and may override any value of ``sim:`` that can be varied, drawn
or not; ``clark campaign`` prints every failing run as such a command.

The schema (:func:`varied`) accepts a number or one distribution; the rules that need
more than the schema (a uniform range written high to low, a fault's window that a draw
could reverse) are :func:`variation_problems`, checked by ``clark validate``.
"""

from __future__ import annotations

import dataclasses
import math
import random
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

from clark_engine.mission.schema_source.common import Schema, obj

if TYPE_CHECKING:
    from clark_engine.mission.model import Mission

DISTRIBUTIONS: Final = ("uniform", "normal", "choice")
"""The ways a value may vary."""

NORMAL_TAIL_SD: Final = 4.0
"""A normal draw is kept within this many standard deviations of its mean (and within its
field's range): a window's rules can then be proved before any run, and a 1-in-30,000
draw is not what a campaign's table is about."""

MAX_CHOICES: Final = 100
"""Longest ``choice`` list."""

#: Keys of a fault's body that may vary (times and shares), and the key of its chance.
FAULT_VARIED_KEYS: Final = ("at_s", "from_s", "to_s", "share")
CHANCE_KEY: Final = "chance"
INJECTED: Final = "injected"
"""The last part of a fault's drawn path (``faults.0.kill.injected``): was it injected."""

Drawn = dict[str, float | bool]
"""Path of each value drawn (or fixed) for one run -> its value, in the mission's order."""


def varied(base: Schema) -> Schema:
    """A number field that may instead be given as a distribution.

    Every bound of ``base`` (its range) applies to each number of the distribution: a
    uniform's ends, a normal's mean, every choice. A normal's draws are kept within the
    range too.
    """
    number = {k: v for k, v in base.items() if k not in ("description", "default")}
    spread = {k: v for k, v in number.items() if k in ("type", "x-unit")}
    spread |= {"minimum": 0}
    if "maximum" in number and "minimum" in number:
        spread["maximum"] = number["maximum"] - number["minimum"]
    elif "maximum" in number:
        spread["maximum"] = number["maximum"]
    forms: list[Schema] = [
        base,
        obj(
            "Drawn once per run, evenly between two numbers (the lower first).",
            {
                "uniform": {
                    "type": "array",
                    "description": "The lower and the upper end.",
                    "items": number,
                    "minItems": 2,
                    "maxItems": 2,
                }
            },
            required=["uniform"],
        ),
        obj(
            "Drawn once per run from a normal distribution, kept within "
            f"{NORMAL_TAIL_SD:g} standard deviations of the mean and within the field's range.",
            {
                "normal": obj(
                    "Its mean and standard deviation.",
                    {
                        "mean": number | {"description": "The mean."},
                        "sd": spread | {"description": "The standard deviation."},
                    },
                    required=["mean", "sd"],
                )
            },
            required=["normal"],
        ),
        obj(
            "Drawn once per run among these values, each as likely.",
            {
                "choice": {
                    "type": "array",
                    "description": "The values.",
                    "items": number,
                    "minItems": 1,
                    "maxItems": MAX_CHOICES,
                }
            },
            required=["choice"],
        ),
    ]
    out: Schema = {"anyOf": forms, "description": base.get("description", "")}
    for key in ("x-unit", "default"):
        if key in base:
            out[key] = base[key]
    out["x-varied"] = True
    out["x-expected"] = (
        "a number or a distribution ({uniform: [LOW, HIGH]}, {normal: {mean: M, sd: S}} "
        "or {choice: [A, B, ...]})"
    )
    return out


def is_distribution(value: Any) -> bool:
    """True for a distribution as written (``{uniform: [...]}``...), False for a number."""
    return isinstance(value, Mapping) and len(value) == 1 and next(iter(value)) in DISTRIBUTIONS


def value_range(value: Any) -> tuple[float, float] | None:
    """The smallest and largest value ``value`` can take, or None if it is not a number.

    A normal's range is its mean plus or minus :data:`NORMAL_TAIL_SD` standard deviations
    (its field's range narrows it further when drawn).
    """
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return float(value), float(value)
    if not is_distribution(value):
        return None
    ((kind, body),) = value.items()
    try:
        if kind == "uniform":
            low, high = (float(x) for x in body)
            return low, high
        if kind == "normal":
            mean, sd = float(body["mean"]), float(body["sd"])
            return mean - NORMAL_TAIL_SD * sd, mean + NORMAL_TAIL_SD * sd
        numbers = [float(x) for x in body]
        return min(numbers), max(numbers)
    except (TypeError, ValueError, KeyError):
        return None


def draw(value: Any, rng: random.Random, bounds: tuple[float, float] | None = None) -> float:
    """One draw of ``value`` (a number is itself), within ``bounds`` when given."""
    if not is_distribution(value):
        return float(value)
    ((kind, body),) = value.items()
    if kind == "uniform":
        low, high = float(body[0]), float(body[1])
        out = rng.uniform(low, high)
    elif kind == "normal":
        mean, sd = float(body["mean"]), float(body["sd"])
        out = min(max(rng.gauss(mean, sd), mean - NORMAL_TAIL_SD * sd), mean + NORMAL_TAIL_SD * sd)
    else:
        out = float(rng.choice(list(body)))
    if bounds is not None:
        out = min(max(out, bounds[0]), bounds[1])
    return out


def _rng(seed: int, path: str) -> random.Random:
    """The generator of one varied value in one run: its own, so draws do not shift."""
    return random.Random(f"{seed}:vary:{path}")


@dataclass(frozen=True, slots=True)
class VariedField:
    """A value of the mission that may vary.

    Attributes:
        path: Where it is, dotted (``sim.wind.speed_mps``, ``faults.0.kill.at_s``).
        value: As written: a number, a distribution, or None when not written (a
            ``sim:`` key that only ``--vary`` gives).
        bounds: The field's range, for draws and for ``--vary``.
        flag: A fault's ``injected`` (true or false), not a number.
    """

    path: str
    value: Any
    bounds: tuple[float, float]
    flag: bool = False

    @property
    def is_varied(self) -> bool:
        """Drawn per run (a distribution, or a fault's chance)."""
        return self.flag or is_distribution(self.value)


def _bounds(schema: Schema) -> tuple[float, float]:
    """A number field's range; open ends are infinite."""
    low = schema.get("minimum", schema.get("exclusiveMinimum"))
    high = schema.get("maximum", schema.get("exclusiveMaximum"))
    return (
        -math.inf if low is None else float(low),
        math.inf if high is None else float(high),
    )


def _sim_fields(schema: Schema, written: Mapping[str, Any], prefix: str) -> Iterator[VariedField]:
    """Every varied-capable field of ``schema`` (the ``sim`` object), written or not."""
    for key, prop in schema.get("properties", {}).items():
        path = f"{prefix}.{key}"
        here = written.get(key) if isinstance(written, Mapping) else None
        if prop.get("x-varied"):
            yield VariedField(path, here, _bounds(prop["anyOf"][0]))
        elif prop.get("type") == "object":
            yield from _sim_fields(prop, here if isinstance(here, Mapping) else {}, path)


def _fault_fields(faults: Sequence[Mapping[str, Any]]) -> Iterator[VariedField]:
    for index, fault in enumerate(faults):
        if len(fault) != 1:
            continue
        ((kind, body),) = fault.items()
        if not isinstance(body, Mapping):
            continue
        for key in FAULT_VARIED_KEYS:
            if key in body:
                bounds = (0.0, 1.0) if key == "share" else (0.0, math.inf)
                yield VariedField(f"faults.{index}.{kind}.{key}", body[key], bounds)
        if CHANCE_KEY in body:
            yield VariedField(f"faults.{index}.{kind}.{INJECTED}", body[CHANCE_KEY], (0, 1), True)


def varied_fields(
    sim_schema: Schema, sim: Mapping[str, Any], faults: Sequence[Mapping[str, Any]]
) -> list[VariedField]:
    """Every value of the mission that a run may draw or ``--vary`` may fix, in order."""
    return [*_sim_fields(sim_schema, sim, "sim"), *_fault_fields(faults)]


class VaryError(ValueError):
    """A ``--vary`` that names no varied value or gives a value it cannot take."""


def parse_vary(texts: Sequence[str], fields: Sequence[VariedField]) -> dict[str, float | bool]:
    """``PATH=VALUE`` texts -> fixed values, checked against the mission's fields.

    Raises:
        VaryError: The text is not ``PATH=VALUE``, names no value that varies (the
            message lists those that do), or gives a value out of the field's range.
    """
    by_path = {f.path: f for f in fields}
    fixed: dict[str, float | bool] = {}
    for text in texts:
        path, sep, raw = text.partition("=")
        path, raw = path.strip(), raw.strip()
        if not sep or not path or not raw:
            raise VaryError(f"--vary {text[:80]!r}: write PATH=VALUE, e.g. sim.radio_loss=0.05")
        field = by_path.get(path)
        if field is None:
            known = ", ".join(f.path for f in fields if f.is_varied or f.path.startswith("sim."))
            raise VaryError(
                f"--vary {path[:80]!r}: the mission has no such value to vary; "
                f"it has: {known or 'none'}"
            )
        if field.flag:
            if raw.lower() not in ("true", "false"):
                raise VaryError(f"--vary {path}: give true or false, not {raw[:40]!r}")
            fixed[path] = raw.lower() == "true"
            continue
        try:
            number = float(raw)
        except ValueError:
            raise VaryError(f"--vary {path}: {raw[:40]!r} is not a number") from None
        low, high = field.bounds
        if not (math.isfinite(number) and low <= number <= high):
            raise VaryError(f"--vary {path}: {raw[:40]} is outside {low:g}..{high:g}")
        fixed[path] = number
    return fixed


def _set(tree: dict[str, Any], parts: Sequence[str], value: Any) -> None:
    for part in parts[:-1]:
        child = tree.get(part)
        tree[part] = child = dict(child) if isinstance(child, Mapping) else {}
        tree = child
    tree[parts[-1]] = value


def draw_run(
    sim_schema: Schema,
    sim: Mapping[str, Any],
    faults: Sequence[Mapping[str, Any]],
    seed: int,
    fixed: Mapping[str, float | bool] | None = None,
) -> tuple[dict[str, Any], list[int], list[dict[str, Any]], Drawn]:
    """One run's draw of every varied value.

    Args:
        sim_schema: The mission schema's ``sim`` object (for where values may vary).
        sim: The mission's ``sim:`` as written.
        faults: The mission's ``faults:`` as written.
        seed: The run's seed.
        fixed: Values given by ``--vary`` (path -> value), used instead of a draw.

    Returns:
        The ``sim`` settings with every value a number; the indexes of the faults that
        are injected; those faults with every value a number (and no ``chance``); and
        what was drawn or fixed, path -> value, in the mission's order (a value written
        as a plain number and not fixed is not listed).
    """
    fixed = dict(fixed or {})
    out_sim: dict[str, Any] = _plain_copy(sim)
    drawn: Drawn = {}
    fields = varied_fields(sim_schema, sim, faults)
    out_faults = [{kind: dict(body) for kind, body in fault.items()} for fault in faults]
    for field in fields:
        if field.path in fixed:
            value: float | bool = fixed[field.path]
        elif field.is_varied:
            rng = _rng(seed, field.path)
            if field.flag:
                value = rng.random() < float(field.value)
            else:
                # Six significant digits: the value printed (and given back to --vary
                # by a campaign's reproduce command) is exactly the value flown.
                value = float(f"{draw(field.value, rng, field.bounds):.6g}")
        else:
            continue
        drawn[field.path] = value
        parts = field.path.split(".")
        if parts[0] == "sim":
            _set(out_sim, parts[1:], value)
        elif not field.flag:
            out_faults[int(parts[1])][parts[2]][parts[3]] = value
    injected: list[int] = []
    for index, fault in enumerate(out_faults):
        ((kind, body),) = fault.items() if len(fault) == 1 else ((None, {}),)
        if kind is None:
            continue
        chance = body.pop(CHANCE_KEY, None)
        path = f"faults.{index}.{kind}.{INJECTED}"
        if chance is None or drawn.get(path, True):
            injected.append(index)
    return out_sim, injected, [out_faults[i] for i in injected], drawn


def _plain_copy(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _plain_copy(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain_copy(v) for v in value]
    return value


def sim_schema() -> Schema:
    """The shipped mission schema's ``sim`` object: where values may vary."""
    from clark_engine.mission.schemas import validator

    sim: Schema = validator("mission").schema["properties"]["sim"]
    return sim


def mission_varied_fields(mission: Mission) -> list[VariedField]:
    """:func:`varied_fields` of a validated mission."""
    return varied_fields(sim_schema(), mission.sim, mission.faults)


def resolve_mission(
    mission: Mission, seed: int, fixed: Mapping[str, float | bool] | None = None
) -> tuple[Mission, Drawn]:
    """The mission as one run flies it, and what was drawn for it.

    Every varied value drawn from ``seed`` (or fixed by ``fixed``), faults whose chance
    did not come up left out. A mission with nothing varied and nothing fixed comes back
    as it is: a dry run that declares no variation is the run it always was.
    """
    sim, injected, faults, drawn = draw_run(sim_schema(), mission.sim, mission.faults, seed, fixed)
    if not drawn:
        return mission, drawn
    locations = [mission.fault_locations[i] for i in injected]
    return dataclasses.replace(mission, sim=sim, faults=faults, fault_locations=locations), drawn


def variation_problems(
    sim_schema: Schema, sim: Mapping[str, Any], faults: Sequence[Mapping[str, Any]]
) -> list[tuple[str, str, str]]:
    """Rules on varied values beyond their schema: (path, code, message) for each broken.

    - A uniform's ends in order (E-VALUE).
    - A fault's window that no draw can reverse: its ``from_s`` can never be drawn at or
      after its ``to_s`` (E-FAULT-WINDOW).
    """
    problems: list[tuple[str, str, str]] = []
    for field in varied_fields(sim_schema, sim, faults):
        value = field.value
        if is_distribution(value) and "uniform" in value:
            span = value_range(value)
            if span is not None and span[0] > span[1]:
                problems.append(
                    (
                        field.path,
                        "E-VALUE",
                        f"{{uniform: [{span[0]:g}, {span[1]:g}]}} runs backwards; write the "
                        f"lower end first: [{span[1]:g}, {span[0]:g}]",
                    )
                )
    for index, fault in enumerate(faults):
        if len(fault) != 1:
            continue
        ((kind, body),) = fault.items()
        if not isinstance(body, Mapping):
            continue
        start, end = body.get("from_s"), body.get("to_s")
        if not (is_distribution(start) or is_distribution(end)):
            continue  # plain numbers: the fault's own rules (faults.fault_problems)
        start_range, end_range = value_range(start), value_range(end)
        if start_range is None or end_range is None:
            continue
        if start_range[1] >= end_range[0]:
            problems.append(
                (
                    f"faults.{index}.{kind}",
                    "E-FAULT-WINDOW",
                    f"a draw could reverse the {kind} window: from_s can be as late as "
                    f"{start_range[1]:g} s and to_s as early as {end_range[0]:g} s; make "
                    "every from_s earlier than every to_s",
                )
            )
    return problems
