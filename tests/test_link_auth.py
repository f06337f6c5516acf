"""Key files, tags and replay windows."""

from __future__ import annotations

import hashlib
import hmac
import os
import stat
from pathlib import Path

import pytest

from clark_engine.errors import ClarkError
from clark_engine.link import KeyFileError, generate_key_file, load_key
from clark_engine.link.auth import CounterStore, ReplayWindow, Tagger
from clark_engine.link.packet import MAX_COUNTER

# ------------------------------------------------------------------ key files


def test_keygen_writes_64_hex_characters_readable_by_the_owner_only(tmp_path: Path) -> None:
    path = tmp_path / "mission.key"
    generate_key_file(path)
    text = path.read_text(encoding="ascii")
    assert len(text) == 65
    assert text.endswith("\n")
    int(text, 16)  # hex
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert load_key(path) == bytes.fromhex(text)
    assert len(load_key(path)) == 32


def test_keygen_makes_a_different_key_each_time(tmp_path: Path) -> None:
    generate_key_file(tmp_path / "a.key")
    generate_key_file(tmp_path / "b.key")
    assert load_key(tmp_path / "a.key") != load_key(tmp_path / "b.key")


def test_keygen_refuses_to_overwrite(tmp_path: Path) -> None:
    path = tmp_path / "mission.key"
    generate_key_file(path)
    before = path.read_bytes()
    with pytest.raises(KeyFileError, match="refusing to overwrite") as caught:
        generate_key_file(path)
    assert caught.value.file == str(path)
    assert isinstance(caught.value, ClarkError)
    assert path.read_bytes() == before
    assert before.decode().strip() not in str(caught.value)


def test_keygen_refuses_to_follow_a_symlink(tmp_path: Path) -> None:
    target = tmp_path / "elsewhere"
    (tmp_path / "mission.key").symlink_to(target)
    with pytest.raises(KeyFileError):
        generate_key_file(tmp_path / "mission.key")
    assert not target.exists()


def test_keygen_into_a_missing_folder_explains(tmp_path: Path) -> None:
    with pytest.raises(KeyFileError, match="cannot create"):
        generate_key_file(tmp_path / "no" / "mission.key")


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604, 0o660, 0o602, 0o620, 0o700 | 0o004])
def test_a_key_file_others_can_reach_is_refused(tmp_path: Path, mode: int) -> None:
    path = tmp_path / "mission.key"
    generate_key_file(path)
    path.chmod(mode)
    with pytest.raises(KeyFileError, match="chmod 600") as caught:
        load_key(path)
    assert str(path) in str(caught.value)
    assert path.read_text().strip() not in str(caught.value)


def test_an_owner_only_key_file_is_accepted_whatever_the_owner_bits(tmp_path: Path) -> None:
    path = tmp_path / "mission.key"
    generate_key_file(path)
    path.chmod(0o400)
    assert len(load_key(path)) == 32


@pytest.mark.parametrize(
    "content",
    [
        b"",
        b"00" * 31 + b"\n",
        b"00" * 33 + b"\n",
        b"zz" * 32 + b"\n",
        b"0x" + b"00" * 31 + b"\n",
        b"00" * 32 + b"\nmore\n",
        b"\x00" * 32,
        b"a" * 10_000,
    ],
)
def test_a_key_file_that_is_not_a_key_is_refused_without_quoting_it(
    tmp_path: Path, content: bytes
) -> None:
    path = tmp_path / "mission.key"
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as out:
        out.write(content)
    with pytest.raises(KeyFileError, match="64 hex characters") as caught:
        load_key(path)
    if content.strip():
        assert content.decode("latin-1").strip()[:20] not in str(caught.value)


def test_uppercase_hex_and_crlf_are_accepted(tmp_path: Path) -> None:
    path = tmp_path / "mission.key"
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as out:
        out.write(b"AB" * 32 + b"\r\n")
    assert load_key(path) == b"\xab" * 32


def test_a_missing_key_file_says_where_to_look(tmp_path: Path) -> None:
    with pytest.raises(KeyFileError, match="key_file") as caught:
        load_key(tmp_path / "nope.key")
    assert caught.value.file == str(tmp_path / "nope.key")


def test_a_folder_is_not_a_key_file(tmp_path: Path) -> None:
    folder = tmp_path / "keys"
    folder.mkdir(mode=0o700)
    with pytest.raises(KeyFileError, match="regular file"):
        load_key(folder)


def test_a_fifo_is_refused_without_hanging(tmp_path: Path) -> None:
    fifo = tmp_path / "mission.key"
    os.mkfifo(fifo, 0o600)
    with pytest.raises(KeyFileError, match="regular file"):
        load_key(fifo)


# ------------------------------------------------------------------ tags


def test_the_tag_is_truncated_hmac_sha256() -> None:
    key, data = b"k" * 32, b"header and bundle"
    tagger = Tagger(key)
    assert tagger.tag(data) == hmac.new(key, data, hashlib.sha256).digest()[:12]
    assert tagger.tag(data) == tagger.tag(data)  # the keyed state is reused, not consumed
    assert tagger.verify(data, tagger.tag(data))
    assert not tagger.verify(data + b"!", tagger.tag(data))
    assert not tagger.verify(data, tagger.tag(data)[:11])
    assert "k" * 8 not in repr(tagger)


def test_a_short_key_is_refused() -> None:
    with pytest.raises(ValueError, match="16 bytes"):
        Tagger(b"")


# ------------------------------------------------------------------ replay window


def test_replay_window_basics() -> None:
    window = ReplayWindow()
    assert window.highest == -1
    assert window.is_fresh(0)
    assert window.is_fresh(5)
    window.commit(5)
    assert not window.is_fresh(5)
    assert window.is_fresh(4)
    assert window.is_fresh(6)
    window.commit(3)
    assert not window.is_fresh(3)
    window.commit(70)  # 65 ahead: everything before 7 is now too old
    assert window.highest == 70
    assert not window.is_fresh(6)
    assert window.is_fresh(7)
    assert not window.is_fresh(70)
    assert "highest=70" in repr(window)


def test_a_jump_across_the_whole_counter_space_is_cheap() -> None:
    # Regression (found by benchmarks/fuzz_link.py): the bitmap was shifted by the raw
    # distance, so a counter near 2**48 tried to build a 2**48-bit integer.
    window = ReplayWindow()
    window.commit(5)
    window.commit(MAX_COUNTER)
    assert window.highest == MAX_COUNTER
    assert not window.is_fresh(5)
    assert window.is_fresh(MAX_COUNTER - 63)
    assert not window.is_fresh(MAX_COUNTER - 64)


def test_is_fresh_changes_nothing() -> None:
    window = ReplayWindow()
    window.commit(10)
    for _ in range(3):
        assert window.is_fresh(1_000)
    assert window.highest == 10


def test_counter_store_reserves_blocks(tmp_path: Path) -> None:
    store = CounterStore(tmp_path / "c", block_size=10)
    assert store.load() == 0
    assert store.reserve(1) == 10
    assert store.load() == 10
    assert store.reserve(11) == 20
    assert "block_size=10" in repr(store)
    with pytest.raises(ValueError):
        CounterStore(tmp_path / "c", block_size=0)
