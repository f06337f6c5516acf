"""A campaign run in a process of its own: ``python -m clark_engine.campaign.child FOLDER``.

Reads the :class:`~clark_engine.campaign.runs.RunSpec` from ``FOLDER/spec.pickle``, flies
the run in this process and writes its :class:`~clark_engine.campaign.runs.RunResult` to
``FOLDER/result.pickle``; exit 0 when the result is written. The worker that started it
(:func:`~clark_engine.campaign.runs.fly_isolated`) stops its process group on a timeout:
SIGTERM becomes an exit here, so that the run's SITL processes are stopped in order and
their instances given back before SIGKILL would come.
"""

from __future__ import annotations

import pickle
import signal
import sys
from pathlib import Path
from types import FrameType

from clark_engine.campaign.runs import RunSpec, fly_here


def _exit_on_term(signum: int, _frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)


def main(argv: list[str]) -> int:
    """Fly the run in ``argv[0]``'s spec; write its result beside it."""
    signal.signal(signal.SIGTERM, _exit_on_term)
    folder = Path(argv[0])
    spec = pickle.loads((folder / "spec.pickle").read_bytes())
    if not isinstance(spec, RunSpec):
        print(f"{folder / 'spec.pickle'} holds no run", file=sys.stderr)
        return 2
    result = fly_here(spec)
    staged = folder / "result.pickle.part"
    staged.write_bytes(pickle.dumps(result))
    staged.rename(folder / "result.pickle")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
