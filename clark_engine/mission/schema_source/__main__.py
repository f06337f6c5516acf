"""Write every schema to ``schemas/``: ``python -m clark_engine.mission.schema_source``."""

from __future__ import annotations

import sys
from pathlib import Path

from clark_engine.mission.schema_source.render import SCHEMA_FILES, render


def main() -> int:
    """Regenerate the schema files in the repository's schemas/ folder."""
    out = Path(__file__).resolve().parents[3] / "schemas"
    out.mkdir(exist_ok=True)
    for file_name in SCHEMA_FILES:
        (out / file_name).write_text(render(file_name), encoding="utf-8")
        print(f"wrote schemas/{file_name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
