"""The mission control station's web view (docs/station-view.md).

- :mod:`clark_engine.station.view_model`: what the page shows, as JSON-able dicts, built from
  the station's runtime (pure: no clock, no socket, no thread), and the operator's
  commands carried out through it and followed until they take effect; its parts:
  :mod:`~clark_engine.station.view_protocol` (the protocol's basics),
  :mod:`~clark_engine.station.view_hello` (the ``hello``: agents, modes, plan),
  :mod:`~clark_engine.station.view_rows` (rows, track points, photos, as the replay
  builds them too), :mod:`~clark_engine.station.view_log` (the mission-log copy) and
  :mod:`~clark_engine.station.view_commands` (the commands' lifecycles);
- :mod:`clark_engine.station.alarms`: the station's alarms (a breach, a near miss, a
  failsafe) judged from what the vehicles report against their envelopes (pure), for the
  live view and the replay;
- :mod:`clark_engine.station.server`: the aiohttp server on its own thread and event loop
  (the page, its static files, the WebSocket), with the token and origin checks; beside
  it :mod:`~clark_engine.station.access` (address, token),
  :mod:`~clark_engine.station.page_messages` (what a page sends, checked),
  :mod:`~clark_engine.station.connections` (the connection caps) and
  :mod:`~clark_engine.station.log_throttle` (floods of log lines);
- :mod:`clark_engine.station.live_view`: the glue to whatever runs the station (its
  ``ViewHost``): snapshots published from the loop's ticks, the operator's commands
  handed to the loop through a queue and a wake-up pipe, so the loop never waits for
  the web; ``clark run --view`` uses it with the real-time shell;
- :mod:`clark_engine.station.rehearsal_view`: the same over a real-time dry run
  (``clark dry-run --realtime --station``), with the mission's checks judged as it runs;
- :mod:`clark_engine.station.replay` and :mod:`clark_engine.station.replay_command`: the page over a
  finished run's logs, with a time slider (``clark replay``); the fleet CSVs read in
  :mod:`~clark_engine.station.replay_fleet`, the page's messages at any time built by
  :mod:`~clark_engine.station.replay_frames`.

Layers (DESIGN.md): this package imports ``runtime``, ``link``, ``mission``, ``sim`` (the
rehearsal) and ``log_checks`` (the replay); none of them imports it: the shell and the
dry run are handed the view through small protocols.
"""
