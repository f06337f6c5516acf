"""Behaviours: what a mission can ``use:``, one module each, and their registry.

Each behaviour is one module in this package exporting ``BEHAVIOR``, a
:class:`~clark_engine.behaviors.declaration.Behavior` that holds everything about
it: its typed parameters (from which its mission and config schemas, defaults and
reference come), its checks, how the compiler resolves it, its traits, its plan
and signal, and its runtime class. :func:`behaviors` is the one registry: the
built-ins below, in the order the language reference lists them. Every ``use:``
is resolved against it when a mission loads, and every compiled state's
behaviour when a config loads, so nothing is looked up by string in flight.

An installed Python package adds behaviours through the entry-point group
``clark_engine.behaviors`` (:data:`GROUP`): each entry point names a
:class:`Behavior`, a module exporting ``BEHAVIOR`` (or ``BEHAVIORS``), or a list of
them; the registry lists them after the built-ins, each with its distribution as
its origin. A plugin that fails to import, or declares a name that is already
taken, is a :class:`PluginError` naming it (exit code 2: the installation is at
fault, not the mission). See docs/plugins.md.

Importing this package imports no runtime code (``clark validate`` must stay
fast and never load the flight libraries).
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from types import MappingProxyType, ModuleType
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.declaration import (
    NO_TRAITS,
    Behavior,
    CompileContext,
    Params,
    Plan,
    Traits,
    UseContext,
    param,
)
from clark_engine.errors import UsageError

if TYPE_CHECKING:
    from clark_engine.behaviors.base import BehaviorRuntime
    from clark_engine.runtime.config import StateSpec

#: The built-in behaviours' modules, in the order the language reference lists them.
BUILT_IN = (
    "waypoint",
    "waypoint_tour",
    "follow_agent",
    "orbit",
    "doublet",
    "sine_sweep",
    "photo_trigger",
    "survey",
    "hold",
    "set_mode",
    "wait",
    "terminate",
    "takeoff",
    "land",
    "return_home",
)

#: The entry-point group through which installed packages add behaviours.
GROUP = "clark_engine.behaviors"

_registry: dict[str, Behavior] = {}
_in_schemas: ContextVar[bool] = ContextVar("clark_plugins_in_schemas", default=False)


class PluginError(UsageError):
    """A behaviour plugin failed to load, or declares a name that is already taken."""


def _load() -> dict[str, Behavior]:
    if not _registry:
        found: dict[str, Behavior] = {}
        for name in BUILT_IN:
            module = importlib.import_module(f"clark_engine.behaviors.{name}")
            behavior: Behavior = module.BEHAVIOR
            found[behavior.name] = behavior
        _load_plugins(found)
        _registry.update(found)
    return _registry


def _declared(loaded: Any) -> list[Any]:
    """What an entry point's object declares: one behaviour, a module's, or a list."""
    if isinstance(loaded, ModuleType):
        loaded = getattr(loaded, "BEHAVIORS", None) or getattr(loaded, "BEHAVIOR", None)
    if isinstance(loaded, Behavior):  # a named tuple itself: not a list of them
        return [loaded]
    if isinstance(loaded, list | tuple):
        return list(loaded)
    return [loaded]


def _load_plugins(found: dict[str, Behavior]) -> None:
    """Add every installed plugin's behaviours to ``found``, in a stable order."""
    from importlib.metadata import entry_points

    points = sorted(
        entry_points(group=GROUP),
        key=lambda e: (e.dist.name if e.dist is not None else "", e.name),
    )
    for point in points:
        dist = point.dist.name if point.dist is not None else point.value
        where = f"behaviour plugin {dist!r} (entry point {point.name} = {point.value})"
        try:
            loaded = point.load()
        except Exception as exc:  # a plugin's own bug: report it, never a traceback
            raise PluginError(
                f"{where} failed to load: {type(exc).__name__}: {exc}; fix it, or "
                f"uninstall it (pip uninstall {dist})"
            ) from None
        for behavior in _declared(loaded):
            if not isinstance(behavior, Behavior):
                raise PluginError(
                    f"{where} gives {type(behavior).__name__}, not a "
                    "clark_engine.behaviors.Behavior; see docs/plugins.md"
                )
            taken = found.get(behavior.name)
            if taken is not None:
                owner = "a built-in behaviour" if taken.origin == "built-in" else taken.origin
                raise PluginError(
                    f"{where} declares behaviour {behavior.name!r}, which {owner} "
                    "already declares; rename it in the plugin, or uninstall one of them"
                )
            found[behavior.name] = behavior._replace(origin=dist)


def behaviors() -> Mapping[str, Behavior]:
    """Every behaviour this engine has: name -> declaration, in reference order.

    Loaded on first use (the modules are imported by name, so that a module which
    needs the registry, such as the flow analysis the checks use, can import this
    package without an import cycle).
    """
    return MappingProxyType(_load())


def built_in() -> Mapping[str, Behavior]:
    """The behaviours built into the engine, without any plugin's.

    What the generated schemas and the language reference describe, so that they do not
    depend on what happens to be installed.
    """
    return MappingProxyType({n: b for n, b in _load().items() if b.origin == "built-in"})


def plugins() -> Mapping[str, Behavior]:
    """The behaviours installed plugins add (empty without any)."""
    return MappingProxyType({n: b for n, b in _load().items() if b.origin != "built-in"})


def in_schemas() -> Mapping[str, Behavior]:
    """The behaviours a schema being built describes.

    The built-ins, as the shipped schema files hold them; every behaviour, plugins
    included, while :func:`plugin_schemas` is in effect (``clark schema``, and the
    validators when a plugin is installed).
    """
    return behaviors() if _in_schemas.get() else built_in()


@contextmanager
def plugin_schemas() -> Iterator[None]:
    """Build schemas that describe the plugins' behaviours too, inside this block."""
    token = _in_schemas.set(True)
    try:
        yield
    finally:
        _in_schemas.reset(token)


def traits_of(name: str | None) -> Traits:
    """The traits of the behaviour a state runs; none for no (or an unknown) behaviour."""
    if name is None:
        return NO_TRAITS
    found = _load().get(name)
    return found.traits if found is not None else NO_TRAITS


def make_behavior(spec: StateSpec) -> BehaviorRuntime:
    """Build the runtime object a compiled state runs, from its typed parameters.

    Args:
        spec: A compiled state whose ``primitive`` names a behaviour.

    Raises:
        ConfigError: The state runs no behaviour, or one this engine does not know
            (a config compiled by another version, or edited by hand).
    """
    from clark_engine.runtime.config import ConfigError

    if spec.primitive is None:
        raise ConfigError(f"{spec.source}: state {spec.path!r} runs no primitive")
    found = _load().get(spec.primitive)
    if found is None:
        known = ", ".join(_load())
        raise ConfigError(
            f"{spec.source}: state {spec.path!r} uses primitive {spec.primitive!r}, which this "
            f"engine does not have ({known}); compile the mission again with this clark"
        )
    return found.runtime(found.parameters.from_config(spec.params))


__all__ = [
    "BUILT_IN",
    "GROUP",
    "Behavior",
    "CompileContext",
    "Params",
    "Plan",
    "PluginError",
    "Traits",
    "UseContext",
    "behaviors",
    "built_in",
    "in_schemas",
    "make_behavior",
    "param",
    "plugin_schemas",
    "plugins",
    "traits_of",
]
