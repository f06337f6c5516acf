"""Generate docs/check-codes.md, the page of every finding code, from docs/check-codes.yaml.

The page shows, for each code the engine can report, a minimal file that triggers it and
the exact output of ``clark`` on that file. Those outputs are never written by hand: this
script writes each example's files into an empty temporary folder, runs the real command
there (``clark_engine.cli.main``, in-process, with its output captured) and pastes what it
printed. So the page cannot drift from the engine, and:

* an example that does not report its code fails the build, with what it printed instead;
* a code the engine can emit (any ``"E-..."`` or ``"W-..."`` literal in ``clark_engine/``)
  without an example fails the build, unless it is in :data:`UNDOCUMENTED` with a reason;
* a documented code the engine no longer emits fails the build too.

Usage, from the repository root::

    python tools/gen_check_codes.py           # write docs/check-codes.md
    python tools/gen_check_codes.py --check   # exit 1 if docs/check-codes.md is out of date
    python tools/gen_check_codes.py --stdout  # print instead of writing

Exit codes: 0 done (or up to date), 1 an example is broken, a code is missing, or (with
``--check``) the page is out of date.

The output is deterministic: examples run in a fresh folder each, shown by relative names;
the shipped data folders are shown as ``behaviors/...`` and ``hardware_profiles/...`` (as
from the top of the repository), and any absolute path of the temporary folder as
:data:`FOLDER_SHOWN`. The format of the source file is described at its top.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import json
import os
import re
import shlex
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import docgen  # tools/docgen.py, beside this script
import yaml

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "docs" / "check-codes.yaml"
OUTPUT = ROOT / "docs" / "check-codes.md"
ENGINE = ROOT / "clark_engine"

#: How an absolute path of an example's temporary folder is shown on the page.
FOLDER_SHOWN = "/path/to"

#: A code literal in the engine's source, as ``docs/check-codes.md`` lists it.
CODE_LITERAL = re.compile(r'"([EW]-[A-Z0-9-]+)"')
_CODE = re.compile(r"^[EW]-[A-Z0-9-]+$")
#: One finding line of ``clark validate``'s text output: severity and code.
_FINDING_LINE = re.compile(r"^\S.*?: (error|warning): .*\[([EW]-[A-Z0-9-]+)\]$")
_PYTHON_SETUP = re.compile(r"^python3 -c (?P<code>.+) > (?P<file>\S+)$")

#: Codes the engine can emit that no example on the page demonstrates, each with the reason
#: it cannot be produced from files. Keep it empty: every code so far has an example (even
#: E-YAML-TOO-LARGE, whose example generates a 5 MB file).
UNDOCUMENTED: dict[str, str] = {}

_EXAMPLE_KEYS = frozenset(
    {"files", "setup", "command", "show_files", "show_exit", "expect", "exit"}
)
_CODE_KEYS = frozenset({"code", "meaning", "example", "after", "fix"})
_GROUP_KEYS = frozenset({"title", "intro", "codes"})
_FILE_KEYS = frozenset({"text", "encoding"})
_TOP_KEYS = frozenset({"title", "intro", "reading", "groups"})


class SourceError(Exception):
    """docs/check-codes.yaml is malformed, or an example does not show what it claims."""


# ----------------------------------------------------------------------------- the source


@dataclass(frozen=True)
class ExampleFile:
    """One file an example writes into its folder.

    Attributes:
        name: Path relative to the folder (``mission.yaml``, ``my_blocks/wiggle.yaml``).
        text: The file's text, shown on the page as written.
        encoding: How the text is saved (``utf-8`` unless an example needs another).
    """

    name: str
    text: str
    encoding: str = "utf-8"


@dataclass(frozen=True)
class Example:
    """Files, the commands that prepare the folder, the command shown, and what it must print.

    Attributes:
        where: Where the example is in the source, for error messages.
        files: Files written into the empty folder, shown on the page in this order.
        setup: Commands run (and shown) before ``command``: ``clark ...``, ``chmod MODE FILE``
            or ``python3 -c CODE > FILE``.
        command: The ``clark`` arguments, as typed (``validate mission.yaml``).
        show_files: Show the files' text on the page.
        show_exit: Show the exit status after the output, as ``echo "exit status $?"`` would.
        expect: Codes the output must report, each with the severity of its prefix.
        exit: The exit status the command must return, when given.
    """

    where: str
    files: tuple[ExampleFile, ...]
    setup: tuple[str, ...]
    command: str
    show_files: bool
    show_exit: bool
    expect: tuple[str, ...]
    exit: int | None


@dataclass(frozen=True)
class CodeEntry:
    """One code's section: what it means, its example, and how to fix it."""

    code: str
    group: str
    meaning: str
    example: Example
    after: str
    fix: str

    @property
    def severity(self) -> str:
        """``error`` for ``E-`` codes, ``warning`` for ``W-`` codes."""
        return "error" if self.code.startswith("E-") else "warning"


@dataclass(frozen=True)
class Group:
    """A section of the page: codes about one subject."""

    title: str
    intro: str
    codes: tuple[CodeEntry, ...]


@dataclass(frozen=True)
class Source:
    """Everything docs/check-codes.yaml holds."""

    title: str
    intro: str
    reading: tuple[str | Example, ...]
    groups: tuple[Group, ...]

    def entries(self) -> list[CodeEntry]:
        """Every code entry, in page order."""
        return [entry for group in self.groups for entry in group.codes]


def _keys(data: Any, allowed: frozenset[str], where: str, required: Sequence[str] = ()) -> None:
    if not isinstance(data, dict):
        raise SourceError(f"{where}: expected a mapping, got {type(data).__name__}")
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise SourceError(
            f"{where}: unknown key(s) {', '.join(unknown)}; allowed: {sorted(allowed)}"
        )
    missing = [key for key in required if key not in data]
    if missing:
        raise SourceError(f"{where}: missing key(s) {', '.join(missing)}")


def _text(data: Mapping[str, Any], key: str, where: str, default: str | None = None) -> str:
    value = data.get(key, default)
    if not isinstance(value, str):
        raise SourceError(f"{where}.{key}: expected text, got {type(value).__name__}")
    return value.strip("\n")


def _list(data: Mapping[str, Any], key: str, where: str) -> list[Any]:
    value = data.get(key)
    if not isinstance(value, list):
        raise SourceError(f"{where}.{key}: expected a list, got {type(value).__name__}")
    return value


def _example(data: Any, where: str, code: str | None) -> Example:
    _keys(data, _EXAMPLE_KEYS, where)
    files: list[ExampleFile] = []
    for name, spec in (data.get("files") or {}).items():
        file_where = f"{where}.files.{name}"
        if isinstance(spec, str):
            files.append(ExampleFile(str(name), spec))
            continue
        _keys(spec, _FILE_KEYS, file_where, required=("text",))
        files.append(
            ExampleFile(
                str(name), _text(spec, "text", file_where) + "\n", spec.get("encoding", "utf-8")
            )
        )
    setup = data.get("setup") or []
    if not isinstance(setup, list) or not all(isinstance(s, str) for s in setup):
        raise SourceError(f"{where}.setup: expected a list of commands")
    expect = list(data.get("expect") or [])
    if code is not None:
        expect.insert(0, code)
    for item in expect:
        if not isinstance(item, str) or not _CODE.match(item):
            raise SourceError(f"{where}.expect: {item!r} is not a code")
    exit_status = data.get("exit")
    if exit_status is not None and not isinstance(exit_status, int):
        raise SourceError(f"{where}.exit: expected a whole number")
    if not files and not setup and exit_status is None:
        raise SourceError(f"{where}: an example needs files, setup commands, or an exit status")
    return Example(
        where=where,
        files=tuple(files),
        setup=tuple(setup),
        command=_text(data, "command", where, "validate mission.yaml"),
        show_files=bool(data.get("show_files", True)),
        show_exit=bool(data.get("show_exit", False)),
        expect=tuple(expect),
        exit=exit_status,
    )


def load_source(path: Path = SOURCE) -> Source:
    """Read and check docs/check-codes.yaml (our own file: ``yaml.safe_load`` is enough).

    Raises:
        SourceError: A key is missing, unknown or of the wrong type, or a code is listed twice.
    """
    where = path.name
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise SourceError(f"{where}: not valid YAML: {exc}") from None
    _keys(data, _TOP_KEYS, where, required=tuple(_TOP_KEYS))
    reading: list[str | Example] = []
    for i, item in enumerate(_list(data, "reading", where)):
        item_where = f"{where}: reading[{i}]"
        _keys(item, frozenset({"text", "example"}), item_where)
        if "text" in item:
            reading.append(_text(item, "text", item_where))
        else:
            reading.append(_example(item["example"], f"{item_where}.example", None))
    groups: list[Group] = []
    seen: set[str] = set()
    for g, group in enumerate(_list(data, "groups", where)):
        group_where = f"{where}: groups[{g}]"
        _keys(group, _GROUP_KEYS, group_where, required=tuple(_GROUP_KEYS))
        title = _text(group, "title", group_where)
        entries: list[CodeEntry] = []
        for entry in _list(group, "codes", group_where):
            _keys(entry, _CODE_KEYS, group_where, required=("code", "meaning", "example", "fix"))
            code = entry["code"]
            code_where = f"{where}: {code}"
            if not isinstance(code, str) or not _CODE.match(code):
                raise SourceError(f"{group_where}: {code!r} is not a code (E-... or W-...)")
            if code in seen:
                raise SourceError(f"{code_where}: the code is listed twice")
            seen.add(code)
            entries.append(
                CodeEntry(
                    code=code,
                    group=title,
                    meaning=_text(entry, "meaning", code_where),
                    example=_example(entry["example"], f"{code_where}: example", code),
                    after=_text(entry, "after", code_where, ""),
                    fix=_text(entry, "fix", code_where),
                )
            )
        groups.append(Group(title, _text(group, "intro", group_where), tuple(entries)))
    return Source(
        title=_text(data, "title", where),
        intro=_text(data, "intro", where),
        reading=tuple(reading),
        groups=tuple(groups),
    )


def engine_codes(package: Path = ENGINE) -> set[str]:
    """Every code the engine can emit: each ``"E-..."``/``"W-..."`` literal in its source."""
    codes: set[str] = set()
    for source in sorted(package.rglob("*.py")):
        if "_generated" in source.parts:
            continue
        codes.update(CODE_LITERAL.findall(source.read_text(encoding="utf-8")))
    return codes


# ----------------------------------------------------------------------------- running


@dataclass
class Run:
    """What an example printed: the transcript shown on the page, and the command's result.

    Attributes:
        transcript: Every command (``$ ...``) and its output, paths made stable.
        output: The output of the example's ``clark`` command alone.
        exit: Its exit status.
    """

    transcript: list[str] = field(default_factory=list)
    output: str = ""
    exit: int = 0


@contextlib.contextmanager
def _inside(folder: Path) -> Iterator[None]:
    """Run with ``folder`` as the working directory, restoring the old one after."""
    old = Path.cwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(old)


def _clark(args: Sequence[str]) -> tuple[str, int]:
    """Run ``clark`` in-process; its standard output and error interleaved, and its exit code."""
    from clark_engine import cli

    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer), contextlib.redirect_stderr(buffer):
        try:
            status = cli.main(list(args))
        except SystemExit as exc:  # argparse's usage errors
            status = exc.code if isinstance(exc.code, int) else 2
    return buffer.getvalue(), status


def _python(code: str, target: Path) -> None:
    """Run a ``python3 -c`` setup command: ``code`` prints the file's content."""
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        exec(code, {"__builtins__": {"print": print}})
    target.write_text(buffer.getvalue(), encoding="utf-8")


def _setup(command: str, folder: Path, where: str) -> str:
    """Run one setup command in ``folder``; returns what it printed."""
    python = _PYTHON_SETUP.match(command)
    if python:
        (code,) = shlex.split(python["code"])
        _python(code, folder / python["file"])
        return ""
    words = shlex.split(command)
    if words[:1] == ["clark"]:
        output, status = _clark(words[1:])
        if status != 0:
            raise SourceError(f"{where}: setup command {command!r} failed:\n{output}")
        return output
    if words[:1] == ["chmod"] and len(words) == 3:
        (folder / words[2]).chmod(int(words[1], 8))
        return ""
    raise SourceError(
        f"{where}: setup command {command!r} is not one of: clark ..., chmod MODE FILE, "
        "python3 -c CODE > FILE"
    )


def _stable(text: str, folder: Path) -> str:
    """Replace what differs between runs and machines: temporary and installation paths."""
    from clark_engine.data import data_dir

    for name in ("behaviors", "hardware_profiles"):
        text = text.replace(str(data_dir(name)) + os.sep, name + "/")
    for shown in {str(folder.resolve()), str(folder)}:
        text = text.replace(shown, FOLDER_SHOWN)
    return text


def run_example(example: Example) -> Run:
    """Write the example's files into an empty folder and run its commands there.

    Raises:
        SourceError: A setup command is not supported or failed.
    """
    run = Run()
    with tempfile.TemporaryDirectory(prefix="clark-codes-") as tmp:
        folder = Path(tmp)
        for item in example.files:
            target = folder / item.name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(item.text.encode(item.encoding))
        with _inside(folder):
            for command in example.setup:
                run.transcript.append(f"$ {command}")
                run.transcript.extend(
                    _stable(_setup(command, folder, example.where), folder).splitlines()
                )
            output, run.exit = _clark(shlex.split(example.command))
            run.output = _stable(output, folder)
    shown = f"$ clark {example.command}"
    if example.show_exit:
        shown += '; echo "exit status $?"'
    run.transcript.append(shown)
    run.transcript.extend(run.output.splitlines())
    if example.show_exit:
        run.transcript.append(f"exit status {run.exit}")
    return run


def _reported(output: str) -> set[tuple[str, str]]:
    """(severity, code) of every finding in text or JSON output."""
    if output.lstrip().startswith("{"):
        payload = json.loads(output)
        return {(f["severity"], f["code"]) for f in payload["findings"]}
    found = set()
    for line in output.splitlines():
        match = _FINDING_LINE.match(line)
        if match:
            found.add((match[1], match[2]))
    return found


def check_run(example: Example, run: Run) -> list[str]:
    """Problems with what an example printed: a code it should report, or the wrong exit."""
    problems = []
    reported = _reported(run.output)
    for code in example.expect:
        severity = "error" if code.startswith("E-") else "warning"
        if (severity, code) not in reported:
            problems.append(
                f"{example.where}: `clark {example.command}` did not report {code} as {severity}"
            )
    if example.exit is not None and run.exit != example.exit:
        problems.append(
            f"{example.where}: `clark {example.command}` exited {run.exit}, not {example.exit}"
        )
    if problems:
        problems[-1] += "; it printed:\n" + "\n".join(f"    {line}" for line in run.transcript)
    return problems


# ----------------------------------------------------------------------------- rendering


def anchor(title: str) -> str:
    """The anchor GitHub gives a heading: lower case, spaces to dashes, punctuation dropped."""
    return re.sub(r"[^a-z0-9 _-]", "", title.lower()).replace(" ", "-")


def _fence(lang: str, body: str) -> list[str]:
    return [f"```{lang}", body.rstrip("\n"), "```", ""]


def render_example(example: Example, run: Run) -> list[str]:
    """The files of an example (captioned when not just ``mission.yaml``) and its transcript."""
    lines: list[str] = []
    if example.show_files:
        caption = len(example.files) > 1 or any(f.name != "mission.yaml" for f in example.files)
        for item in example.files:
            if caption:
                lines += [f"`{item.name}`:", ""]
            lines += _fence("yaml", item.text)
    lines += _fence("text", "\n".join(run.transcript))
    return lines


def render(source: Source, runs: Callable[[Example], Run]) -> str:
    """The whole page, Markdown, ending in one newline."""
    lines = [
        f"# {source.title}",
        "",
        "<!-- Generated by tools/gen_check_codes.py from docs/check-codes.yaml; "
        "do not edit by hand. -->",
        "",
        source.intro,
        "",
        "- [Reading findings](#reading-findings)",
        *(f"- [{g.title}](#{anchor(g.title)})" for g in source.groups),
        "- [Index of codes](#index-of-codes)",
        "",
        "## Reading findings",
        "",
    ]
    for item in source.reading:
        if isinstance(item, str):
            lines += [item, ""]
        else:
            lines += render_example(item, runs(item))
    for group in source.groups:
        lines += [f"## {group.title}", "", group.intro, ""]
        for entry in group.codes:
            lines += [
                f"### {entry.code}",
                "",
                f"**{entry.severity.capitalize()}.** {entry.meaning}",
                "",
            ]
            lines += render_example(entry.example, runs(entry.example))
            if entry.after:
                lines += [entry.after, ""]
            lines += [f"**Fix:** {entry.fix}", ""]
    lines += ["## Index of codes", "", "| Code | Severity | Group |", "|---|---|---|"]
    for entry in sorted(source.entries(), key=lambda e: e.code):
        lines.append(
            f"| [{entry.code}](#{entry.code.lower()}) | {entry.severity} | "
            f"[{entry.group}](#{anchor(entry.group)}) |"
        )
    text = "\n".join(lines).rstrip() + "\n"
    return re.sub(r"\n{3,}", "\n\n", text)


# ----------------------------------------------------------------------------- main


def _import_engine() -> None:
    """Make ``clark_engine`` importable when the script runs from a checkout."""
    try:
        importlib.import_module("clark_engine")
    except ModuleNotFoundError:
        sys.path.insert(0, str(ROOT))
        importlib.import_module("clark_engine")


def generate(source_path: Path = SOURCE) -> str:
    """Run every example and build the page.

    Raises:
        SourceError: The source is malformed, an example does not report its code, or the
            page and the engine disagree on which codes exist. The message lists every problem.
    """
    _import_engine()
    source = load_source(source_path)
    problems: list[str] = []
    documented = {entry.code for entry in source.entries()}
    emitted = engine_codes()
    for code in sorted(emitted - documented - set(UNDOCUMENTED)):
        problems.append(
            f"{code}: the engine can report it, but docs/check-codes.yaml has no example"
        )
    for code in sorted(documented - emitted):
        problems.append(
            f"{code}: docs/check-codes.yaml documents it, but the engine never reports it"
        )
    for code in sorted(set(UNDOCUMENTED) & documented):
        problems.append(f"{code}: has an example; remove it from UNDOCUMENTED")
    cache: dict[int, Run] = {}

    def runs(example: Example) -> Run:
        if id(example) not in cache:
            run = run_example(example)
            problems.extend(check_run(example, run))
            cache[id(example)] = run
        return cache[id(example)]

    text = render(source, runs)
    if problems:
        raise SourceError("\n".join(problems))
    return text


def main(argv: Sequence[str] | None = None) -> int:
    """Write, print or check docs/check-codes.md; returns the exit code."""
    return docgen.run(
        OUTPUT,
        generate,
        argv,
        tool="gen_check_codes.py",
        description="Generate docs/check-codes.md from its examples.",
        errors=(SourceError,),
    )


if __name__ == "__main__":
    sys.exit(main())
