"""The commands about a mission before anything flies: validate, compile, explain, etc.

``clark validate``, ``compile``, ``explain``, ``schema``, ``behaviors``, ``keygen`` and
``examples``. Separate from the others
because ``clark validate`` must stay fast: this module imports, at its top, nothing but
the standard library and the engine's errors, and each command imports the mission
layer it needs inside its function (never the runtime or its flight libraries:
``tests/test_cli.py``, ``test_validate_does_not_import_flight_libraries``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from clark_engine.cli.arguments import EXIT_INVALID, EXIT_OK, EXIT_USAGE
from clark_engine.errors import UsageError

if TYPE_CHECKING:
    from clark_engine.mission.findings import Finding
    from clark_engine.mission.validate import Validation


def _summary(result: Validation) -> str:
    errors = len(result.errors)
    warnings = len(result.findings) - errors
    if errors:
        text = f"{result.file}: invalid ({errors} error{'s' * (errors != 1)}"
        if warnings:
            text += f", {warnings} warning{'s' * (warnings != 1)}"
        return text + ")"
    text = f"{result.file}: valid {result.kind}"
    if warnings:
        text += f" ({warnings} warning{'s' * (warnings != 1)})"
    return text


#: Findings whose message ends in advice that is the same every time: the text from this
#: marker on is given once per command, later findings of the code say "(see above)".
_ADVICE_ONCE = {"W-NO-KEY": ": make one with"}


class _FindingPrinter:
    """Prints a command's findings: warnings hidden by ``--quiet``, repeated advice once."""

    def __init__(self, quiet: bool = False) -> None:
        self.quiet = quiet
        self.advised: set[str] = set()

    def text(self, finding: Finding) -> str:
        """The finding's line, its advice cut when an earlier finding already gave it."""
        marker = _ADVICE_ONCE.get(finding.code)
        if marker is not None and marker in finding.message:
            if finding.code in self.advised:
                short = finding.message.split(marker)[0] + " (see the advice above)"
                finding = dataclasses.replace(finding, message=short)
            self.advised.add(finding.code)
        return finding.format_text()

    def __call__(self, result: Validation, stream: TextIO) -> None:
        for finding in result.findings:
            if self.quiet and not finding.is_error:
                continue
            print(self.text(finding), file=stream)


def cmd_validate(args: argparse.Namespace) -> int:
    """Validate files and report every finding."""
    from clark_engine.validation import validate_file

    results = []
    usage_failed = False
    print_findings = _FindingPrinter(args.quiet)
    for name in args.paths:
        try:
            results.append(validate_file(Path(name), name))
        except UsageError as exc:
            usage_failed = True
            print(f"clark validate: error: {exc}", file=sys.stderr)
    if args.format == "json":
        payload = {
            "files": [
                {
                    "file": r.file,
                    "kind": r.kind,
                    "valid": r.ok,
                    "errors": len(r.errors),
                    "warnings": len(r.findings) - len(r.errors),
                }
                for r in results
            ],
            "findings": [f.to_json() for r in results for f in r.findings],
        }
        print(json.dumps(payload, indent=2))
    else:
        for result in results:
            print_findings(result, sys.stdout)
            print(_summary(result))
    if usage_failed:
        return EXIT_USAGE
    return EXIT_OK if all(r.ok for r in results) else EXIT_INVALID


def _load_valid(path_text: str, command: str, quiet: bool = False) -> Validation | int:
    """Validate a mission for compile/explain: findings to stderr, exit code on failure."""
    from clark_engine.validation import validate_file

    result = validate_file(Path(path_text), path_text)
    if result.kind != "mission" and result.ok:
        print(
            f"clark {command}: error: {path_text} is a {result.kind}, not a mission",
            file=sys.stderr,
        )
        return EXIT_USAGE
    _FindingPrinter(quiet)(result, sys.stderr)
    if result.mission is None:
        print(
            f"{_summary(result)}; nothing {'written' if command == 'compile' else 'shown'}",
            file=sys.stderr,
        )
        return EXIT_INVALID
    return result


def cmd_compile(args: argparse.Namespace) -> int:
    """Compile a mission into one JSON config per agent."""
    from clark_engine.mission.compiler import compile_mission, write_configs

    loaded = _load_valid(args.mission, "compile", args.quiet)
    if isinstance(loaded, int):
        return loaded
    mission = loaded.mission
    assert mission is not None
    files = compile_mission(mission, args.agent or None)
    # With --agent, the other agents' configs from an earlier compile stay; without it, a
    # config of an agent no longer in the mission is removed with the rest of the old output.
    keep = [name for name in mission.agents if name not in files] if args.agent else []
    target = write_configs(files, Path(args.output), mission.name, keep)
    for name in files:
        print(f"wrote {target / (name + '.json')}")
    return EXIT_OK


def cmd_explain(args: argparse.Namespace) -> int:
    """Print the resolved behaviour of one or every agent."""
    from clark_engine.mission.explain import mermaid, tree

    loaded = _load_valid(args.mission, "explain", args.quiet)
    if isinstance(loaded, int):
        return loaded
    mission = loaded.mission
    assert mission is not None
    names = args.agent or list(mission.agents)
    for name in names:
        if name not in mission.agents:
            raise UsageError(
                f"{args.mission}: there is no agent {name!r}; agents: {', '.join(mission.agents)}"
            )
    for i, name in enumerate(names):
        agent = mission.agents[name]
        if i:
            print()
        if args.format in ("tree", "both"):
            sys.stdout.write(tree(mission, agent))
        if args.format == "both":
            print()
        if args.format in ("mermaid", "both"):
            print("```mermaid")
            sys.stdout.write(mermaid(mission, agent))
            print("```")
    return EXIT_OK


def cmd_schema(args: argparse.Namespace) -> int:
    """Print one of the shipped JSON Schemas."""
    from clark_engine.mission.schemas import SCHEMA_NAMES, schema_text

    name = args.name.removesuffix(".schema.json").replace("_", "-")
    if name not in SCHEMA_NAMES:
        raise UsageError(
            f"there is no schema {args.name!r}; choose one of: {', '.join(SCHEMA_NAMES)}"
        )
    sys.stdout.write(schema_text(name))
    return EXIT_OK


def cmd_behaviors(args: argparse.Namespace) -> int:
    """List every behaviour a mission can use: name, origin (built-in or plugin), summary.

    Plugins are installed Python packages that declare behaviours through the
    ``clark_engine.behaviors`` entry-point group (docs/plugins.md); a plugin that
    fails to load is reported here, as everywhere, with exit code 2.
    """
    from clark_engine.behaviors import behaviors

    if args.blocks:
        return _list_blocks(args.json)
    declared = behaviors()
    if args.json:
        rows = [
            {"name": b.name, "origin": b.origin, "summary": b.summary} for b in declared.values()
        ]
        print(json.dumps(rows, indent=2))
        return EXIT_OK
    name_w = max(len(name) for name in declared)
    origin_w = max(len(b.origin) for b in declared.values())
    for b in declared.values():
        print(f"{b.name:<{name_w}}  {b.origin:<{origin_w}}  {b.summary}")
    return EXIT_OK


def _origin_label(shown: str, origin: str, group: str) -> str:
    """``shipped``, or the distribution of the plugin whose folder a file is shown under."""
    from clark_engine.mission.plugin_data import plugin_folders

    if not origin:
        return "shipped"
    return next((p.dist for p in plugin_folders(group) if shown.startswith(p.shown + "/")), origin)


def _print_rows(rows: list[dict[str, str]], as_json: bool, columns: tuple[str, ...]) -> None:
    if as_json:
        print(json.dumps(rows, indent=2))
        return
    widths = [max([len(c), *(len(r[c]) for r in rows)]) for c in columns[:-1]]
    for row in rows:
        cells = [f"{row[c]:<{w}}" for c, w in zip(columns, widths, strict=False)]
        print("  ".join([*cells, row[columns[-1]]]))


def _refused(findings: list[Finding]) -> bool:
    """Print the errors among ``findings`` (a name two folders declare) to stderr."""
    errors = [f for f in findings if f.is_error]
    for finding in errors:
        print(finding.format_text(), file=sys.stderr)
    return bool(errors)


def _list_blocks(as_json: bool) -> int:
    """``clark behaviors --blocks``: every behaviour block, shipped or from a plugin."""
    from clark_engine.mission.plugin_data import BLOCKS_GROUP
    from clark_engine.mission.validate import installed_libraries

    _, blocks = installed_libraries()
    rows = []
    for name in blocks.names():
        block = blocks.get(name)
        shown, origin = blocks.origin_of(name)
        rows.append(
            {
                "name": name,
                "origin": _origin_label(shown, origin, BLOCKS_GROUP),
                "file": shown,
                "description": " ".join(block.description.split()) if block else "(invalid)",
            }
        )
    _print_rows(rows, as_json, ("name", "origin", "description"))
    return EXIT_INVALID if _refused(blocks.findings) else EXIT_OK


def cmd_profiles(args: argparse.Namespace) -> int:
    """List every hardware profile a mission can name: name, kind, origin, description.

    The shipped profiles and those installed plugins add through the
    ``clark_engine.hardware_profiles`` entry-point group (docs/plugins.md); a name two of
    them declare is reported (exit code 1), a plugin that fails to load too (exit code 2).
    """
    from clark_engine.mission.plugin_data import PROFILES_GROUP
    from clark_engine.mission.validate import installed_libraries

    profiles, _ = installed_libraries()
    rows = []
    for name in profiles.names(args.kind):
        doc = profiles.document(name)
        data = doc.data if doc is not None and isinstance(doc.data, dict) else {}
        shown, origin = profiles.origin_of(name)
        rows.append(
            {
                "name": name,
                "kind": str(data.get("kind", "?")),
                "origin": _origin_label(shown, origin, PROFILES_GROUP),
                "file": shown,
                "description": " ".join(str(data.get("description", "")).split()),
            }
        )
    _print_rows(rows, args.json, ("name", "kind", "origin", "description"))
    return EXIT_INVALID if _refused(profiles.findings) else EXIT_OK


def cmd_keygen(args: argparse.Namespace) -> int:
    """Write a new ClarkLink key file (32 random bytes, readable by its owner only)."""
    from clark_engine.link.auth import KeyFileError, generate_key_file

    path = Path(args.path)
    if path.is_dir():
        raise UsageError(
            f"{path} is a directory; give the key file's name (e.g. {path}/mission.key)"
        )
    if path.exists():
        raise UsageError(
            f"{path} exists; keygen never overwrites a key (delete it first if you mean to)"
        )
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        generate_key_file(path)
    except KeyFileError as exc:  # cannot be written: an I/O error, exit 2
        raise UsageError(str(exc)) from None
    except OSError as exc:
        raise UsageError(f"cannot write {path}: {exc.strerror or exc}") from None
    print(f"wrote {path} (mode 600); name it in mission.key_file and copy it to every agent")
    return EXIT_OK


def cmd_examples(args: argparse.Namespace) -> int:
    """Copy the shipped example missions, and the schemas their editors' lines name.

    An installed engine keeps its examples inside the package, where a user should not
    edit them; this gives a copy to work on. ``DIR/missions`` and ``DIR/schemas`` keep the
    repository's layout, so each mission's ``$schema=../schemas/...`` line resolves. The
    copy is made in a hidden folder in DIR and moved into place whole: an error leaves
    nothing half-copied, and nothing of the user's is ever overwritten.
    """
    import shutil
    import tempfile

    from clark_engine.data import data_dir

    target = Path(args.dir)
    if target.exists() and not target.is_dir():
        raise UsageError(f"{target} is a file; give a folder to copy the examples into")
    taken = [target / name for name in ("missions", "schemas") if (target / name).exists()]
    if taken:
        names = " and ".join(str(t) for t in taken)
        raise UsageError(
            f"{names} already {'exists' if len(taken) == 1 else 'exist'}; clark examples "
            "never overwrites: give another folder"
        )
    try:
        target.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=".clark-examples-", dir=target) as staging:
            for name in ("missions", "schemas"):
                shutil.copytree(data_dir(name), Path(staging) / name)
            for name in ("missions", "schemas"):
                (Path(staging) / name).rename(target / name)
    except OSError as exc:
        raise UsageError(f"cannot copy the examples into {target}: {exc.strerror or exc}") from None
    missions = sorted(p.name for p in (target / "missions").glob("*.yaml"))
    print(f"wrote {len(missions)} example missions to {target / 'missions'}:")
    for name in missions:
        print(f"  {name}")
    print(f"and the JSON Schemas their editor lines name to {target / 'schemas'}")
    print(f"try: clark dry-run {target / 'missions' / 'cooperative_follow.yaml'}")
    return EXIT_OK


__all__ = [
    "cmd_behaviors",
    "cmd_compile",
    "cmd_examples",
    "cmd_explain",
    "cmd_keygen",
    "cmd_profiles",
    "cmd_schema",
    "cmd_validate",
]
