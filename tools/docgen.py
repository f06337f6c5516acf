"""The command-line end shared by the tools that generate a doc page from its sources.

``tools/gen_reference.py`` and ``tools/gen_check_codes.py`` each make one Markdown file;
both are run three ways: to write it, to print it (``--stdout``), and by the tests and
CI to check that the committed file is what its sources make (``--check``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(
    output: Path,
    generate: Callable[[], str],
    argv: Sequence[str] | None,
    *,
    tool: str,
    description: str,
    errors: tuple[type[Exception], ...] = (),
) -> int:
    """Parse ``argv``, then write, print or check ``output``; returns the exit code.

    Args:
        output: The generated file.
        generate: Makes its text.
        argv: The command line (``sys.argv[1:]`` when None).
        tool: The tool's file name in tools/, for the messages.
        description: The tool's one-line description, for ``--help``.
        errors: Exceptions ``generate`` raises for bad sources: reported, exit 1.
    """
    name = output.relative_to(ROOT).as_posix()
    parser = argparse.ArgumentParser(description=description)
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--check", action="store_true", help=f"exit 1 if {name} is out of date")
    group.add_argument("--stdout", action="store_true", help="print instead of writing")
    args = parser.parse_args(argv)
    try:
        text = generate()
    except errors as exc:
        print(f"tools/{tool}: {name} not generated:\n{exc}", file=sys.stderr)
        return 1
    if args.stdout:
        sys.stdout.write(text)
        return 0
    if args.check:
        current = output.read_text(encoding="utf-8") if output.exists() else ""
        if current != text:
            print(f"{name} is out of date; run: python tools/{tool}", file=sys.stderr)
            return 1
        print(f"{name} is up to date")
        return 0
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(text, encoding="utf-8")
    print(f"wrote {name}")
    return 0
