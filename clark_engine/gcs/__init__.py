"""The mission control station's live web view (docs/station-view.md).

- :mod:`clark_engine.gcs.model`: what the page shows, as JSON-able dicts, built from
  the station's runtime (pure: no clock, no socket, no thread);
- :mod:`clark_engine.gcs.server`: the aiohttp server on its own thread and event loop
  (the page, its static files, the WebSocket), with the token and origin checks;
- :mod:`clark_engine.gcs.station`: the glue to the real-time shell: snapshots published
  from the loop's ticks, the operator's commands handed to the loop through a queue and
  a wake-up pipe, so the loop never waits for the web.

Layers (DESIGN.md): this package imports ``runtime`` and ``shells``; nothing there
imports it back.
"""
