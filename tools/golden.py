"""The golden manifest: what the engine makes, byte for byte, so that a move changes none of it.

Issue 20 moves the code into packages by concept. A move must not change what the
engine makes, so before anything moves this tool records the SHA-256 of everything it
makes from the shipped examples, and ``--check`` makes it all again in a temporary
folder and compares. What it covers:

* ``compile/<mission>/``: each example's compiled per-agent configs, as ``clark compile
  -o compile/<mission>`` writes them, and ``findings.txt``, the validator's findings;
* ``dry-run/<mission>/``: each example's seed-1 dry run on the simulated autopilot
  (never SITL): its report folder (``report/``: logs, ``summary.md``, plots), the checks
  and safety tables it printed on stdout (``stdout.txt``), its diagnostics on stderr
  (``stderr.txt``) and its exit code (``outcome.txt``);
* ``generated/``: the files made from the engine's own sources: ``schemas/*.json``,
  ``docs/reference.md``, ``docs/check-codes.md`` and the ClarkLink protobuf module
  (``clarklink_pb2.py`` and ``.pyi``), keyed by what they are rather than where their
  generator lives, so that moving a generator moves no key;
* the list of files itself: a file that appears or disappears is a difference.

What is not reproducible from the seed (the wall-clock figures, the temporary folder's
path, the progress lines written every wall-clock second) is normalised before hashing,
and files whose bytes depend on a library's version are compared only where that
version is installed; the manifest's ``normalised`` and ``version_bound`` say which and
why. An intended change is re-recorded with ``record --reason TEXT``, which lists the
files it changed in the manifest's ``intended_changes``, in the same commit as the change.

Usage, from the repository root::

    python tools/golden.py record                  # write tests/golden/manifest.json
    python tools/golden.py record --reason TEXT    # re-record an intended change
    python tools/golden.py --check                 # exit 1 on any difference (make golden)
    python tools/golden.py --check cooperative_follow copter_takeoff_land   # a subset
    python tools/golden.py --check --part generated --part compile          # fast parts
    python tools/golden.py --check --against HEAD  # show differing lines against HEAD's code

Exit codes: 0 identical, 1 a difference (each printed as ``path: expected sha256 ...,
got ...``, with the first differing lines of a text file when its recorded bytes are at
hand: a generated file as committed, or with ``--against REV`` what that revision's code
makes), 2 a usage or I/O error (a missing or malformed manifest, an unknown mission).
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import hashlib
import importlib
import importlib.util
import io
import json
import os
import re
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from fnmatch import fnmatchcase
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from types import ModuleType
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
MANIFEST = ROOT / "tests" / "golden" / "manifest.json"
MISSIONS = ROOT / "missions"
#: The seed every example is dry-run with.
SEED = 1
#: What the manifest covers, in the order they are made.
PARTS = ("generated", "check-codes", "compile", "dry-run")
#: The one generated file made by running examples (about 20 s): a part of its own, so
#: that a quick check can leave it out (tests/test_docs.py checks it against its source).
CHECK_CODES_KEY = "generated/docs/check-codes.md"

#: What is not reproducible from the seed, and how it is made so before hashing.
NORMALISED: dict[str, str] = {
    "dry-run/*/report/summary.md": (
        "the wall time and the speed-up ('170 simulated seconds in 4.1 s of wall time "
        "(42x real time)') are written as '<wall> s' and '<ratio>x'; the temporary "
        "report folder in the equivalent command is written as '<tmp>'"
    ),
    "dry-run/*/stderr.txt": (
        "the progress lines ('  simulated 214.0 of 417 s (51%)'), written every wall-clock "
        "second, are dropped; the closing line's wall time and speed-up are written as "
        "'<wall> s' and '<ratio>x'; the temporary report folder is written as '<tmp>'"
    ),
}
#: Files whose bytes depend on a library's version, not only on the engine's code: they
#: are compared only where the version they were recorded with is installed.
VERSION_BOUND: dict[str, tuple[str, str]] = {
    "dry-run/*/report/*.png": (
        "matplotlib",
        "byte-identical between runs (two runs of every example compared), but the bytes "
        "depend on matplotlib's version (pyproject allows >=3.8,<4; the PNG metadata names "
        "it) and the FreeType it bundles: an upgrade is not a move",
    ),
    "generated/proto/*": (
        "grpcio-tools",
        "protoc's output depends on its version (pinned in pyproject; tools/gen_proto.py)",
    ),
}
#: Nothing is excluded: every file the runs write is compared (after NORMALISED).
EXCLUDED: dict[str, str] = {}
#: File name endings shown line by line when they differ.
TEXT_SUFFIXES = (".json", ".md", ".txt", ".log", ".csv", ".py", ".pyi")
#: Lines of a text difference shown.
DIFF_LINES = 12

_WALL_SUMMARY = re.compile(r"in [0-9]+(?:\.[0-9]+)? s of wall time \((?:[0-9]+|inf)x real time\)")
_PROGRESS = re.compile(r"^  simulated [0-9.]+ of [0-9.]+ s \([0-9]+%\)\n", re.MULTILINE)
_WALL_STDERR = re.compile(
    r"^(simulated [0-9.]+ s) in [0-9]+(?:\.[0-9]+)? s \((?:[0-9]+|inf)x real time\)$",
    re.MULTILINE,
)


class GoldenError(Exception):
    """A usage or I/O problem (exit code 2): the message says what and where."""


@dataclass(frozen=True)
class Difference:
    """One file that is not as recorded."""

    path: str
    expected: str | None
    """The recorded SHA-256; None when the file was not recorded (it appeared)."""
    got: str | None
    """The SHA-256 made now; None when the file was not made (it disappeared)."""
    lines: tuple[str, ...] = ()
    """The first differing lines of a text file, when its expected bytes are at hand."""

    def format(self) -> str:
        """``path: expected sha256 ..., got ...`` and the differing lines under it."""
        expected = f"sha256 {self.expected}" if self.expected else "no such file"
        got = f"sha256 {self.got}" if self.got else "no such file"
        return "\n".join([f"{self.path}: expected {expected}, got {got}", *self.lines])


@dataclass
class Manifest:
    """tests/golden/manifest.json."""

    files: dict[str, str]
    versions: dict[str, str] = field(default_factory=dict)
    intended_changes: list[dict[str, Any]] = field(default_factory=list)

    def dump(self) -> str:
        """The manifest's text: sorted keys, two-space indent, a trailing newline."""
        data = {
            "about": (
                "SHA-256 of everything tools/golden.py makes from the shipped examples "
                "(see its docstring); `make golden` checks it. Re-record an intended change "
                "with `python tools/golden.py record --reason TEXT` in the same commit."
            ),
            "seed": SEED,
            "files": self.files,
            "excluded": EXCLUDED,
            "normalised": NORMALISED,
            "version_bound": {
                pattern: {
                    "package": package,
                    "recorded_with": self.versions.get(package, ""),
                    "why": why,
                }
                for pattern, (package, why) in VERSION_BOUND.items()
            },
            "intended_changes": self.intended_changes,
        }
        return json.dumps(data, indent=2, sort_keys=True, ensure_ascii=False) + "\n"

    @classmethod
    def load(cls, path: Path) -> Manifest:
        """Read and check a manifest.

        Raises:
            GoldenError: Missing, unreadable or malformed.
        """
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise GoldenError(
                f"{display(path)}: no such manifest; record one with: python tools/golden.py record"
            ) from None
        except (OSError, UnicodeDecodeError) as exc:
            raise GoldenError(f"{display(path)}: cannot read the manifest: {exc}") from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise GoldenError(
                f"{display(path)}:{exc.lineno}:{exc.colno}: not JSON: {exc.msg}"
            ) from None
        files = data.get("files") if isinstance(data, dict) else None
        if not isinstance(files, dict) or not all(
            isinstance(k, str) and isinstance(v, str) and re.fullmatch(r"[0-9a-f]{64}", v)
            for k, v in files.items()
        ):
            raise GoldenError(
                f"{display(path)}: 'files' must map each path to a SHA-256 (64 hex digits)"
            )
        changes = data.get("intended_changes", [])
        if not isinstance(changes, list) or not all(
            isinstance(c, dict) and isinstance(c.get("reason"), str) for c in changes
        ):
            raise GoldenError(
                f"{display(path)}: 'intended_changes' must be a list of objects with a 'reason'"
            )
        bound = data.get("version_bound", {})
        versions = {
            entry["package"]: entry["recorded_with"]
            for entry in (bound.values() if isinstance(bound, dict) else ())
            if isinstance(entry, dict)
            and isinstance(entry.get("package"), str)
            and isinstance(entry.get("recorded_with"), str)
        }
        return cls(files=dict(files), versions=versions, intended_changes=list(changes))


def _own_engine() -> None:
    """Import the engine of this checkout, whatever an editable install points at.

    The manifest gates the code beside it: checking another checkout's engine would
    pass a move it never saw.

    Raises:
        GoldenError: ``clark_engine`` was already imported from elsewhere.
    """
    if str(ROOT) not in sys.path[:1]:
        sys.path.insert(0, str(ROOT))
    engine = importlib.import_module("clark_engine")
    where = Path(engine.__file__ or "").resolve()
    if not where.is_relative_to(ROOT):
        raise GoldenError(f"clark_engine is imported from {where}, not from {ROOT}")


def display(path: Path) -> str:
    """A path as shown in messages: relative to the repository when inside it."""
    try:
        return path.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        return str(path)


def sha256(data: bytes) -> str:
    """The hex SHA-256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def installed(package: str) -> str:
    """The installed version of ``package``, or "" when it is not installed."""
    try:
        return version(package)
    except PackageNotFoundError:
        return ""


# ----------------------------------------------------------------------------- making


def example_missions() -> list[str]:
    """The shipped examples' names (``missions/<name>.yaml``), sorted."""
    return sorted(p.stem for p in MISSIONS.glob("*.yaml"))


def _tool(name: str) -> ModuleType:
    """Import ``tools/<name>.py`` (the generators import their neighbours by plain name)."""
    tools = str(ROOT / "tools")
    if tools not in sys.path:
        sys.path.insert(0, tools)
    return importlib.import_module(name)


def make_generated() -> dict[str, bytes]:
    """The schemas, the language reference and the protobuf module, made from their sources."""
    from clark_engine.mission.schema_source.render import SCHEMA_FILES, render

    made = {f"generated/schemas/{name}": render(name).encode() for name in SCHEMA_FILES}
    made["generated/docs/reference.md"] = _tool("gen_reference").generate().encode()
    if importlib.util.find_spec("grpc_tools") is not None:
        with tempfile.TemporaryDirectory(prefix="clark-golden-proto-") as tmp:
            for path in _tool("gen_proto").generate(Path(tmp)):
                made[f"generated/proto/{path.name}"] = path.read_bytes()
    return made


def make_check_codes() -> dict[str, bytes]:
    """docs/check-codes.md, made by running every one of its examples (about 20 s)."""
    return {CHECK_CODES_KEY: _tool("gen_check_codes").generate().encode()}


def make_compile(name: str, out: Path) -> dict[str, bytes]:
    """``clark compile missions/<name>.yaml -o <out>/compile/<name>``: configs and findings."""
    from clark_engine.mission.compiler import compile_mission, write_configs
    from clark_engine.validation import validate_file

    result = validate_file(MISSIONS / f"{name}.yaml", f"missions/{name}.yaml")
    made = {
        f"compile/{name}/findings.txt": "".join(
            f.format_text() + "\n" for f in result.findings
        ).encode()
    }
    if result.mission is not None:
        folder = out / "compile" / name
        write_configs(compile_mission(result.mission), folder, result.mission.name)
        made.update(_read_tree(folder, f"compile/{name}"))
    return made


def make_dry_run(name: str, out: Path) -> dict[str, bytes]:
    """``clark dry-run missions/<name>.yaml --seed 1 --report ...``, its outputs normalised."""
    from clark_engine.dryrun.command import run_dry_run
    from clark_engine.errors import ClarkError

    report = out / "dry-run" / name / "report"
    stdout, stderr = io.StringIO(), io.StringIO()
    # The mission is named as a user names it, relative to the checkout (the working
    # folder, see make), so that its findings and the report's command name it the same.
    try:
        code = run_dry_run(
            Path("missions") / f"{name}.yaml",
            seed=SEED,
            until_s=None,
            report=report,
            speed=None,
            out=stdout,
            err=stderr,
        ).exit_code
    except ClarkError as exc:  # a usage error is a result too: recorded, not raised
        print(f"error: {exc}", file=stderr)
        code = 2
    prefix = f"dry-run/{name}"
    made = _read_tree(report, f"{prefix}/report") if report.exists() else {}
    made[f"{prefix}/stdout.txt"] = stdout.getvalue().encode()
    made[f"{prefix}/stderr.txt"] = stderr.getvalue().encode()
    made[f"{prefix}/outcome.txt"] = f"exit code {code}\n".encode()
    return {path: normalise(path, data, out) for path, data in made.items()}


def _read_tree(folder: Path, prefix: str) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden ones too), keyed ``prefix/relative path``."""
    return {
        f"{prefix}/{p.relative_to(folder).as_posix()}": p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def normalise(path: str, data: bytes, tmp: Path) -> bytes:
    """Make a file's bytes reproducible from the seed (see :data:`NORMALISED`)."""
    if not any(fnmatchcase(path, pattern) for pattern in NORMALISED):
        return data
    text = data.decode("utf-8")
    for folder in {str(tmp.resolve()), str(tmp)}:
        text = text.replace(folder, "<tmp>")
    text = _WALL_SUMMARY.sub("in <wall> s of wall time (<ratio>x real time)", text)
    text = _PROGRESS.sub("", text)
    text = _WALL_STDERR.sub(r"\1 in <wall> s (<ratio>x real time)", text)
    return text.encode("utf-8")


def part_of(path: str) -> str:
    """The part a manifest key belongs to (:data:`PARTS`)."""
    return "check-codes" if path == CHECK_CODES_KEY else path.split("/", 1)[0]


def mission_of(path: str) -> str | None:
    """The example a compile or dry-run key belongs to; None for a generated file."""
    part, _, rest = path.partition("/")
    return rest.split("/", 1)[0] if part in ("compile", "dry-run") else None


def make(
    parts: Sequence[str],
    missions: Sequence[str],
    out: Path,
    progress: Callable[[str], None] = lambda _: None,
) -> dict[str, bytes]:
    """Make the selected parts for the selected examples in ``out``; path -> bytes.

    Everything is made from the checkout's root, as a user types the commands there: the
    file names a compiled config and a report carry are relative to the working folder
    when inside it, so the bytes would otherwise depend on where the tool was started.
    """
    with contextlib.chdir(ROOT):
        return _make(parts, missions, out, progress)


def _make(
    parts: Sequence[str],
    missions: Sequence[str],
    out: Path,
    progress: Callable[[str], None],
) -> dict[str, bytes]:
    made: dict[str, bytes] = {}
    if "generated" in parts:
        progress("generated files")
        made.update(make_generated())
    if "check-codes" in parts:
        progress("docs/check-codes.md (runs its examples)")
        made.update(make_check_codes())
    for name in missions:
        if "compile" in parts:
            progress(f"compile {name}")
            made.update(make_compile(name, out))
        if "dry-run" in parts:
            progress(f"dry-run {name} --seed {SEED}")
            made.update(make_dry_run(name, out))
    return made


# ----------------------------------------------------------------------------- comparing


def _selected(path: str, parts: Sequence[str], missions: Sequence[str]) -> bool:
    mission = mission_of(path)
    return part_of(path) in parts and (mission is None or mission in missions)


def _bound(path: str) -> str | None:
    """The package whose version ``path``'s bytes depend on, if any."""
    for pattern, (package, _why) in VERSION_BOUND.items():
        if fnmatchcase(path, pattern):
            return package
    return None


def _lines(path: str, expected: bytes, got: bytes) -> tuple[str, ...]:
    """The first differing lines of a text file (a unified diff, cut short)."""
    if not path.endswith(TEXT_SUFFIXES):
        return ()
    try:
        old, new = expected.decode("utf-8"), got.decode("utf-8")
    except UnicodeDecodeError:
        return ()
    diff = list(
        difflib.unified_diff(
            old.splitlines(), new.splitlines(), "expected", "got", n=1, lineterm=""
        )
    )[2:]
    cut = diff[:DIFF_LINES] + (
        [f"... ({len(diff) - DIFF_LINES} more lines)"] if len(diff) > DIFF_LINES else []
    )
    return tuple("    " + line for line in cut)


def _expected_copy(path: str, digest: str, against: Path | None) -> bytes | None:
    """The recorded bytes of ``path`` where a copy is at hand (checked by its hash).

    A folder written by ``--keep`` on the recorded code holds every file; a generated
    file is also in the checkout, as committed.
    """
    candidates: list[Path] = []
    if against is not None:
        candidates.append(against / path)
    if path.startswith("generated/schemas/") or path.startswith("generated/docs/"):
        candidates.append(ROOT / path.removeprefix("generated/"))
    elif path.startswith("generated/proto/"):
        candidates.append(
            ROOT / "clark_engine" / "link" / "_generated" / path.removeprefix("generated/proto/")
        )
    for candidate in candidates:
        with contextlib.suppress(OSError):
            data = candidate.read_bytes()
            if sha256(data) == digest:
                return data
    return None


def compare(
    manifest: Manifest,
    made: Mapping[str, bytes],
    parts: Sequence[str],
    missions: Sequence[str],
    against: Path | None = None,
) -> tuple[list[Difference], list[str]]:
    """The differences between the manifest and what was made, within the selection.

    Returns:
        The differences, sorted by path, and notes on what was not compared and why.
    """
    expected = {k: v for k, v in manifest.files.items() if _selected(k, parts, missions)}
    notes: list[str] = []
    skipped: dict[str, int] = {}
    differences = []
    for path in sorted(set(expected) | set(made)):
        package = _bound(path)
        if package is not None:
            recorded, have = manifest.versions.get(package, ""), installed(package)
            if recorded != have:
                skipped[package] = skipped.get(package, 0) + 1
                continue
        want = expected.get(path)
        data = made.get(path)
        got = sha256(data) if data is not None else None
        if want == got:
            continue
        lines: tuple[str, ...] = ()
        if want is not None and data is not None:
            copy = _expected_copy(path, want, against)
            if copy is not None:
                lines = _lines(path, copy, data)
            elif path.endswith(TEXT_SUFFIXES):
                lines = (
                    "    (to see the differing lines: --against HEAD, or the revision the "
                    "manifest was recorded at)",
                )
        differences.append(Difference(path, want, got, lines))
    for package, count in sorted(skipped.items()):
        notes.append(
            f"{count} file(s) not compared: their bytes depend on {package}, recorded with "
            f"{manifest.versions.get(package) or 'none'}, installed {installed(package) or 'none'}"
        )
    return differences, notes


def check(
    manifest_path: Path = MANIFEST,
    missions: Sequence[str] | None = None,
    parts: Sequence[str] = PARTS,
    keep: Path | None = None,
    against: Path | None = None,
    progress: Callable[[str], None] = lambda _: None,
) -> tuple[list[Difference], list[str]]:
    """Make the selection again in a temporary folder and compare it with the manifest.

    Raises:
        GoldenError: The manifest is missing or malformed, or a mission is unknown.
    """
    manifest = Manifest.load(manifest_path)
    chosen = _missions(missions)
    folder = against if against is None or against.is_dir() else None
    with tempfile.TemporaryDirectory(prefix="clark-golden-") as tmp:
        made = make(parts, chosen, Path(tmp), progress)
    if keep is not None:
        _write(made, keep)
    differences, notes = compare(manifest, made, parts, chosen, folder)
    if against is None or folder is not None or not differences:
        return differences, notes
    # A revision: make the differing parts again on its code, for their lines.
    with tempfile.TemporaryDirectory(prefix="clark-golden-against-") as tmp:
        old = made_at(
            str(against),
            sorted({part_of(d.path) for d in differences}),
            sorted({m for d in differences if (m := mission_of(d.path)) is not None}),
            Path(tmp),
            progress,
        )
        return compare(manifest, made, parts, chosen, old)


def made_at(
    revision: str,
    parts: Sequence[str],
    missions: Sequence[str],
    tmp: Path,
    progress: Callable[[str], None] = lambda _: None,
) -> Path:
    """Make ``parts`` for ``missions`` on the code of a git revision; the folder they are in.

    The revision is exported (``git archive``, which leaves the repository as it is) and
    its own tools/golden.py runs on its own engine with ``--keep``.

    Raises:
        GoldenError: Not a revision of this repository, or its tool failed.
    """
    progress(f"the same again on {revision}, for the differing lines")
    source, kept = tmp / "source", tmp / "kept"
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", "--format=tar", revision],
        capture_output=True,
        check=False,
    )
    if archive.returncode != 0:
        message = archive.stderr.decode(errors="replace").strip()
        raise GoldenError(f"--against {revision}: not a folder, and git says: {message}")
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        tar.extractall(source, filter="data")
    if not (source / "tools" / "golden.py").exists():
        raise GoldenError(f"--against {revision}: that revision has no tools/golden.py")
    selection = [arg for part in parts for arg in ("--part", part)] + list(missions)
    run = subprocess.run(
        [sys.executable, "tools/golden.py", "--check", "--keep", str(kept), *selection],
        cwd=source,
        env={**os.environ, "PYTHONPATH": str(source)},
        capture_output=True,
        text=True,
        check=False,
    )
    if run.returncode not in (0, 1) or not kept.is_dir():
        raise GoldenError(
            f"--against {revision}: its tools/golden.py failed:\n{run.stdout}{run.stderr}"
        )
    return kept


def _missions(names: Sequence[str] | None) -> list[str]:
    known = example_missions()
    if not names:
        return known
    chosen = [Path(n).name.removesuffix(".yaml") for n in names]
    unknown = [n for n in chosen if n not in known]
    if unknown:
        raise GoldenError(
            f"no such example mission: {', '.join(unknown)} (missions/: {', '.join(known)})"
        )
    return sorted(set(chosen))


def _write(made: Mapping[str, bytes], folder: Path) -> None:
    """Write what was made into ``folder`` (``--keep``), for ``--against`` or a look."""
    for path, data in made.items():
        target = folder / path
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)


def record(
    manifest_path: Path = MANIFEST,
    reason: str | None = None,
    progress: Callable[[str], None] = lambda _: None,
    out: Callable[[str], None] = print,
) -> int:
    """Make everything and write the manifest; returns the exit code.

    Re-recording a manifest whose files change needs a reason: the changed paths and
    the reason are appended to ``intended_changes`` (1 and nothing written without one).
    """
    if manifest_path.exists():
        Manifest.load(manifest_path)  # a malformed one is refused before minutes of work
    with tempfile.TemporaryDirectory(prefix="clark-golden-") as tmp:
        made = make(PARTS, example_missions(), Path(tmp), progress)
    return write_manifest(manifest_path, made, reason, out)


def write_manifest(
    manifest_path: Path,
    made: Mapping[str, bytes],
    reason: str | None,
    out: Callable[[str], None] = print,
) -> int:
    """Write the manifest of ``made``; returns the exit code (see :func:`record`)."""
    old = Manifest.load(manifest_path) if manifest_path.exists() else None
    files = {path: sha256(data) for path, data in sorted(made.items())}
    versions = {package: installed(package) for package, _ in VERSION_BOUND.values()}
    changes: list[dict[str, Any]] = list(old.intended_changes) if old is not None else []
    if old is not None:
        changed = {
            path: (
                "added" if path not in old.files else "removed" if path not in files else "changed"
            )
            for path in sorted(set(old.files) | set(files))
            if old.files.get(path) != files.get(path)
        }
        if changed and reason is None:
            out(f"{len(changed)} file(s) differ from {display(manifest_path)}:")
            for path, how in changed.items():
                out(f"  {how}: {path}")
            out("nothing written: if the change is intended, record it with --reason TEXT")
            return 1
        if changed and reason is not None:
            changes.append({"reason": reason, "files": changed})
    manifest = Manifest(files=files, versions=versions, intended_changes=changes)
    manifest_path.parent.mkdir(parents=True, exist_ok=True)
    manifest_path.write_text(manifest.dump(), encoding="utf-8")
    out(f"wrote {display(manifest_path)}: {len(files)} files")
    return 0


# ----------------------------------------------------------------------------- command


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        raise GoldenError(f"{self.prog}: {message} (see --help)")


def build_parser() -> argparse.ArgumentParser:
    """``tools/golden.py record`` or ``tools/golden.py --check [MISSION ...]``."""
    parser = _Parser(
        prog="tools/golden.py",
        description="Record or check the golden manifest (tests/golden/manifest.json).",
    )
    parser.add_argument(
        "words",
        nargs="*",
        metavar="record | MISSION",
        help="`record` writes the manifest; with --check, the examples to check (all if none)",
    )
    parser.add_argument("--check", action="store_true", help="compare; exit 1 on a difference")
    parser.add_argument("--manifest", type=Path, default=MANIFEST, help="the manifest file")
    parser.add_argument(
        "--part",
        action="append",
        choices=PARTS,
        help="with --check: only this part (repeatable; all when none)",
    )
    parser.add_argument("--reason", help="with record: why the recorded files change")
    parser.add_argument("--keep", type=Path, help="with --check: write what was made here")
    parser.add_argument(
        "--against",
        type=Path,
        metavar="REV|DIR",
        help="with --check: show the differing lines of text files against what a git "
        "revision's code makes (made again, only for the differences), or a --keep folder",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the tool; returns the exit code (0 identical, 1 different, 2 usage or I/O)."""

    def progress(text: str) -> None:
        print(f"  {text}", file=sys.stderr, flush=True)

    try:
        args = build_parser().parse_args(argv)
        _own_engine()
        if args.check:
            if args.reason is not None:
                raise GoldenError("--reason goes with record, not --check")
            differences, notes = check(
                args.manifest, args.words, tuple(args.part or PARTS), args.keep, args.against,
                progress,
            )  # fmt: skip
            for note in notes:
                print(f"note: {note}")
            for difference in differences:
                print(difference.format())
            if differences:
                print(
                    f"{len(differences)} file(s) differ from {display(args.manifest)}; if the "
                    "change is intended: python tools/golden.py record --reason TEXT"
                )
                return 1
            print(f"identical to {display(args.manifest)}")
            return 0
        if args.words != ["record"]:
            raise GoldenError("say `record` or `--check [MISSION ...]` (see --help)")
        if args.part or args.keep or args.against:
            raise GoldenError(
                "record makes everything: --part, --keep and --against go with --check"
            )
        return record(args.manifest, args.reason, progress)
    except GoldenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
