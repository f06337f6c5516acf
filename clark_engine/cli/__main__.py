"""Allow ``python -m clark_engine.cli``, the same as the ``clark`` command."""

from clark_engine.cli import console_main

console_main()
