"""What goes wrong with real ArduPilot SITL: the errors of :mod:`clark_engine.sitl`.

Apart from the launcher because the instance numbers' reservation
(:mod:`clark_engine.sitl.instances`) raises them too, and the dry run's SITL backend and
the command line catch them without starting anything.
"""

from __future__ import annotations

from clark_engine.errors import ClarkError


class SitlError(ClarkError):
    """SITL could not be started, reached or stopped; the message ends with its log's tail."""


class SitlNotFound(SitlError):
    """No SITL launcher where the command line or the environment says, or nowhere said."""
