"""cooperative_follow with its pair's separation lowered, so that a full dry run passes.

The example's Slash B parks within about 1 m of Slash A (its follow tolerance lets it),
under the default 5 m separation between vehicles, so every full dry run of it fails
the dry run's safety judgement (docs/dry-run.md#safety). Tests about other things (the
report, exit codes, splitting a run) fly this copy, where the pair keeps 0.5 m, until
the example itself declares an envelope; from then on they fly the example as it is.
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"
PAIR_SEPARATION = "envelope:\n  separation: [{between: [slash_a, slash_b], min_m: 0.5}]\n"


def passing_follow(folder: Path) -> Path:
    """The mission to fly: a copy in ``folder`` with the pair's separation, or the example."""
    text = FOLLOW.read_text(encoding="utf-8")
    if "\nenvelope:" in text:
        return FOLLOW
    path = folder / FOLLOW.name
    path.write_text(text.rstrip("\n") + "\n\n" + PAIR_SEPARATION, encoding="utf-8")
    return path
