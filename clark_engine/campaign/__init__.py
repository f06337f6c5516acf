"""``clark campaign``: many dry runs of one mission, each its own sample of the world.

One dry run is one seed of a noisy world (GPS noise, radio loss, tick phases, and the
mission's declared variations: wind, GPS error, bursty links, faults with drawn times
or a chance). A campaign flies the mission N times, run ``i`` with its own seed derived
from the campaign's seed and ``i`` (:func:`~clark_engine.campaign.runs.run_seed`), and
reports how often each check held, with a 95 % Wilson interval, the spread of the
figures the checks look at, every failing run with the one command that reproduces it,
and the pass rate against each drawn factor.

- :mod:`~clark_engine.campaign.stats`: the Wilson score interval and percentiles.
- :mod:`~clark_engine.campaign.runs`: one run, in a worker: its seed, its result (small
  and picklable), and the isolation of a run in its own process group with a timeout.
- :mod:`~clark_engine.campaign.pool`: where runs go (a local process pool, in this
  process, or a Dask cluster), retries of infrastructure failures, progress, Ctrl-C.
- :mod:`~clark_engine.campaign.report`: the table, ``summary.md`` and the plots.
- :mod:`~clark_engine.campaign.command`: the command's logic.
"""
