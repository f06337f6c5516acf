"""The strict loader: YAML 1.2 scalars, duplicate keys, boolean words, bounds, positions."""

from __future__ import annotations

import tracemalloc

import pytest

from clark_engine.mission.yaml_loader import (
    MAX_DEPTH,
    YamlLoadError,
    decode_text,
    load_yaml,
)


def codes(text: str) -> list[str]:
    return [f.code for f in load_yaml(text, "t.yaml").findings]


def fatal(text: str) -> str:
    with pytest.raises(YamlLoadError) as info:
        load_yaml(text, "t.yaml")
    return info.value.findings[0].code


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("a: 1:30", "1:30"),  # no sexagesimal: stays text
        ("a: 010", 10),  # no YAML 1.1 octal
        ("a: 0o10", 8),
        ("a: 0x1F", 31),
        ("a: 2026-11-21", "2026-11-21"),  # no timestamps
        ("a: 1_000", "1_000"),  # no underscores in numbers
        ("a: 1.5e3", 1500.0),
        ("a: true", True),
        ("a: False", False),
        ("a: ~", None),
        ("a: null", None),
        ("a: 'yes'", "yes"),  # quoted words are plain text, no finding
        ("a: .5", 0.5),
    ],
)
def test_scalars_follow_yaml_1_2(text: str, value: object) -> None:
    doc = load_yaml(text, "t.yaml")
    assert doc.data == {"a": value}
    assert type(doc.data["a"]) is type(value)
    assert doc.findings == []


@pytest.mark.parametrize("word", ["yes", "No", "ON", "off"])
def test_bool_words_as_values_are_reported_and_kept_as_text(word: str) -> None:
    doc = load_yaml(f"flag: {word}\n", "t.yaml")
    assert doc.data == {"flag": word}
    (finding,) = doc.findings
    assert finding.code == "E-YAML-BOOL-WORD"
    assert (finding.location.line, finding.location.column) == (1, 7)
    assert "true or false" in finding.message


def test_bool_words_as_keys_are_reported_at_the_key() -> None:
    doc = load_yaml("a: 1\non: 2\n", "t.yaml")
    (finding,) = doc.findings
    assert finding.code == "E-YAML-BOOL-WORD"
    assert (finding.location.line, finding.location.column) == (2, 1)
    assert doc.data == {"a": 1, "on": 2}


def test_every_duplicate_key_is_reported() -> None:
    doc = load_yaml("a: 1\nb: 2\na: 3\nb: 4\na: 5\n", "t.yaml")
    dups = [f for f in doc.findings if f.code == "E-YAML-DUPLICATE-KEY"]
    assert [f.location.line for f in dups] == [3, 4, 5]
    assert doc.data == {"a": 1, "b": 2}  # the first one is kept, the rest reported


def test_positions_of_keys_and_values() -> None:
    doc = load_yaml("top:\n  inner:\n    - 1\n    - {x: 2}\n", "t.yaml")
    assert doc.location(("top", "inner", 1, "x")).line == 4
    assert doc.location(("top", "inner", 1, "x")).column == 11
    assert doc.location(("top", "inner"), key=True).column == 3
    # a path that was never written falls back to its nearest written ancestor
    missing = doc.location(("top", "inner", 1, "nope"))
    assert (missing.line, missing.column) == (4, 7)


def test_merge_keys_explicit_keys_win() -> None:
    doc = load_yaml("d: &d {x: 1, y: 2}\ne: {<<: *d, y: 3}\n", "t.yaml")
    assert doc.data["e"] == {"x": 1, "y": 3}
    assert doc.findings == []


def test_alias_bomb_is_rejected_quickly_and_small() -> None:
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        prev, cur = chr(96 + i), chr(97 + i)
        lines.append(f"{cur}: &{cur} [" + ",".join([f"*{prev}"] * 9) + "]")
    bomb = "\n".join(lines) + "\n"
    assert len(bomb) < 1100
    tracemalloc.start()
    try:
        with pytest.raises(YamlLoadError) as info:
            load_yaml(bomb, "bomb.yaml")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert info.value.findings[0].code == "E-YAML-ALIAS"
    assert peak < 50 * 1024 * 1024


def test_nesting_is_bounded() -> None:
    assert fatal("[" * (MAX_DEPTH + 5) + "]" * (MAX_DEPTH + 5)) == "E-YAML-DEPTH"


def test_self_referencing_alias_is_rejected() -> None:
    assert fatal("a: &a [*a]\n") in ("E-YAML-DEPTH", "E-YAML-ALIAS")


@pytest.mark.parametrize(
    ("text", "code"),
    [
        ("", "E-YAML-EMPTY"),
        ("# only a comment\n", "E-YAML-EMPTY"),
        ("a: 1\n---\nb: 2\n", "E-YAML-MULTI-DOC"),
        ("a:\n\tb: 1\n", "E-YAML-SYNTAX"),
        ("a: [1, 2\n", "E-YAML-SYNTAX"),
    ],
)
def test_unreadable_documents(text: str, code: str) -> None:
    assert fatal(text) == code


def test_syntax_error_points_at_the_problem() -> None:
    with pytest.raises(YamlLoadError) as info:
        load_yaml("a: 1\nb: [1, 2\nc: 3\n", "t.yaml")
    finding = info.value.findings[0]
    assert finding.location.line == 3
    assert "YAML" not in finding.message or "syntax" in finding.message


def test_unsupported_tags_are_reported() -> None:
    assert codes("a: !!python/object:os.system 1\n") == ["E-YAML-TAG"]
    assert codes("a: !!str 12\n") == []


def test_non_finite_numbers_are_reported() -> None:
    assert codes("a: .inf\n") == ["E-YAML-VALUE"]


def test_binary_and_non_utf8_bytes_are_refused() -> None:
    with pytest.raises(YamlLoadError) as info:
        decode_text(b"\x7fELF\x00\x01\x02", "x.bin")
    assert info.value.findings[0].code == "E-YAML-BINARY"
    with pytest.raises(YamlLoadError) as info:
        decode_text(b"a: 1\nb: \xff\xfe\n", "x.yaml")
    assert info.value.findings[0].code == "E-YAML-BINARY"
    assert info.value.findings[0].location.line == 2


def test_utf8_bom_is_accepted() -> None:
    assert decode_text("\ufeffa: 1\n".encode(), "x.yaml") == "a: 1\n"


def test_libyaml_parser_is_used_when_available() -> None:
    import yaml

    from clark_engine.mission import yaml_loader

    if yaml.__with_libyaml__:
        assert yaml_loader.HAVE_LIBYAML
        assert issubclass(yaml_loader._Loader, yaml_loader._CParser)
