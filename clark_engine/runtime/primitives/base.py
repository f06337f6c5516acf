"""The lifecycle every runtime primitive follows (py_trees' Behaviour).

``__init__`` takes the validated, resolved parameters from the compiled config
and nothing else; ``start`` runs on entering the state; ``update`` runs every
tick, never blocks, and reports running, done or failed; ``stop`` cleans up
when the state is left for any reason; ``on_payload`` receives payload events
while the state is active. Each primitive lives in its own module beside the
mission layer's declaration of its parameters (clark_engine.mission.primitives).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.events import PayloadEvent


class Primitive:
    """Base class of the runtime primitives.

    Attributes:
        name: The primitive's name as missions write it after ``use:``.
        params: The resolved parameters from the compiled config.
    """

    name: ClassVar[str] = ""

    def __init__(self, params: Mapping[str, Any]) -> None:
        """Keep the parameters; no side effects here (the state may never be entered)."""
        self.params = params

    def start(self, ctx: PrimitiveContext) -> None:
        """Called when the state is entered, before its first ``update``."""

    def update(self, ctx: PrimitiveContext) -> Status:
        """Called once per tick while the state is active; must not block."""
        return Status.RUNNING

    def stop(self, ctx: PrimitiveContext) -> None:
        """Called when the state is left (finished, interrupted, or terminated)."""

    def on_payload(self, ctx: PrimitiveContext, event: PayloadEvent) -> None:
        """Called for each payload event delivered while the state is active."""
