"""The schema files and their exact text, shared by the generator and the drift test."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any


def _builders() -> dict[str, Callable[[], dict[str, Any]]]:
    # Imported here so that importing this module stays cheap.
    from clark_engine.mission.schema_source import (
        agent_config,
        behavior,
        hardware_profile,
        mission,
    )

    return {
        "mission.schema.json": mission.build,
        "behavior.schema.json": behavior.build,
        "hardware_profile.schema.json": hardware_profile.build,
        "agent_config.schema.json": agent_config.build,
    }


SCHEMA_FILES = (
    "mission.schema.json",
    "behavior.schema.json",
    "hardware_profile.schema.json",
    "agent_config.schema.json",
)


def render(file_name: str) -> str:
    """The exact text of one schema file: sorted-free, 2-space JSON, newline at the end."""
    return json.dumps(_builders()[file_name](), indent=2, ensure_ascii=False) + "\n"
