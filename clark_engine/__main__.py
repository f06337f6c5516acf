"""Allow ``python -m clark_engine``, the same as the ``clark`` command."""

from clark_engine.cli import main

raise SystemExit(main())
