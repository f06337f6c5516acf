"""Measure an XBee unplug: what reaches stderr, and how soon the radio notices.

One emulated 900HP (``clark_engine.sim.xbee_emulator``) under an ``XBeeRadio`` with
the default ``health_interval_s`` (0.5 s), pulled out (its pty's master closed: the
adapter's side reads as a vanished USB device, and digi-xbee's reader spins on it),
then plugged back. Run it with stderr captured and no logging configured, as
``clark run`` has it; it prints, per run, how long the loss took to notice and how
many of the library's lines were counted rather than written (``counted``):

    python benchmarks/bench_xbee_unplug.py 2>/tmp/err.txt; wc -lc /tmp/err.txt

Run against an older tree (``PYTHONPATH=...``) for the figures before the change.
"""

from __future__ import annotations

import sys
import threading
import time

from clark_engine.io.xbee import XBeeRadio
from clark_engine.sim.xbee_emulator import XBeeEmulator

ADDRESS = "0013A20041000001"
RUNS = 3


def one_unplug() -> tuple[float, int | None]:
    """Unplug and plug back once: (milliseconds until noticed, library lines counted)."""
    pause = threading.Event()
    with XBeeEmulator(throughput_bps=None) as emulator:
        emulated = emulator.add_radio(ADDRESS)
        radio = XBeeRadio(emulated.port)
        radio.open()
        try:
            start_s = time.monotonic()
            emulated.unplug()
            while radio.link_up:
                pause.wait(0.001)
            noticed_ms = (time.monotonic() - start_s) * 1000
            emulated.plug()
            while not radio.link_up:
                pause.wait(0.01)
        finally:
            radio.close()
    return noticed_ms, getattr(radio.stats, "library_lines", None)


def main() -> None:
    """Print one line per run."""
    for run in range(RUNS):
        noticed_ms, counted = one_unplug()
        print(f"run {run + 1}: loss noticed after {noticed_ms:.0f} ms; counted {counted}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
