"""ClarkLink authentication: packet tags, replay windows, counter persistence, key files.

A mission with a key authenticates every packet with HMAC-SHA256 over the whole
packet (header and bundle, so the mission id, sender, destination and counter
are covered too), truncated to :data:`~clark_engine.link.packet.TAG_BYTES`
(12 bytes, 96 bits: a forger's chance per try is 2**-96, and the radio's
bandwidth is what a longer tag would cost). The counter in the header, never
reused by a sender, and a per-sender :class:`ReplayWindow` at the receiver stop
a recorded packet from being played back.

The key is secret material: it never appears in an exception message, a repr or
a log line, and :func:`load_key` refuses a key file that anyone but its owner
can read or write.
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import os
import secrets
import stat
import tempfile
from pathlib import Path

from clark_engine.errors import ClarkError
from clark_engine.link.errors import ReplayStoreError
from clark_engine.link.packet import MAX_COUNTER, TAG_BYTES

KEY_BYTES = 32
#: Counters reserved per write of the counter store. A write costs an fsync
#: (tens of milliseconds on a mission computer's SD card, enough to overrun a
#: tick), so it should be rare: at 100 packets per second a block of 65536 lasts
#: 11 minutes. A restart skips at most one block, out of 2**48 counters.
DEFAULT_COUNTER_BLOCK = 65_536
#: How long of each sender's traffic a receiver's *live* replay marks reserve, in
#: seconds. The live marks (see :class:`ReplayStore`) are written without an fsync, so
#: their writes are cheap; they reserve, per sender, the counters it is expected to use
#: in this long at its slowest recent rate, rounded down: none for a sender slower than
#: one packet in this long, whose exact mark is written with each of its packets. After
#: a crash of the agent's process, the receiver refuses at most about this long of a
#: sender's genuine packets that it had never seen.
DEFAULT_REPLAY_RESERVE_S = 0.5
#: How long of each sender's traffic the *durable* replay marks reserve, in seconds:
#: what counts after the computer itself restarts (power loss, kernel crash). Their
#: writes cost an fsync (tens of milliseconds on a mission computer's SD card, enough
#: to overrun a tick), made about once in this long for every sender faster than one
#: packet in it (one write renews every sender), plus once per packet of each slower
#: one. A computer's restart usually takes longer than this, so the senders' counters
#: are past the marks when the agent is back.
DEFAULT_REPLAY_DURABLE_RESERVE_S = 10.0
#: The most counters of one sender reserved per write, whatever its rate (a sender
#: faster than this many packets per reservation costs more writes): a bound on what a
#: crash can make the receiver refuse if a sender's rate falls just before it.
DEFAULT_REPLAY_BLOCK = 1024
_BOOT_ID_FILE = Path("/proc/sys/kernel/random/boot_id")
_REPLAY_LIVE_MAGIC = "clarklink-replay-live 1"
_REPLAY_MAGIC = "clarklink-replay 1"
_MAX_REPLAY_FILE_BYTES = 4 << 20  # 65535 senders at 31 bytes a line, with room
_MAX_KEY_FILE_BYTES = 256  # a key file is 65 bytes; never read a large file whole


class KeyFileError(ClarkError):
    """A key file that cannot be used: missing, exposed to other users, or not a key.

    The message names the file and what to do; it never contains the file's content.
    """


class CounterStoreError(ClarkError):
    """The packet counter's high-water mark cannot be read or written.

    Sending stops rather than risk reusing a counter: peers would reject the
    packets as replays.
    """


class Tagger:
    """Computes and checks packet tags under one key.

    The HMAC's keyed state is computed once and copied per packet, which is
    about a third faster than keying afresh each time.
    """

    __slots__ = ("_keyed",)

    def __init__(self, key: bytes) -> None:
        """Key the HMAC.

        Raises:
            ValueError: The key is shorter than 16 bytes (key files hold 32).
        """
        if len(key) < 16:
            raise ValueError("a ClarkLink key must be at least 16 bytes (key files hold 32)")
        self._keyed = hmac.new(bytes(key), digestmod=hashlib.sha256)

    def __repr__(self) -> str:
        return "Tagger(<key hidden>)"

    def tag(self, data: bytes) -> bytes:
        """HMAC-SHA256 of ``data``, truncated to TAG_BYTES."""
        mac = self._keyed.copy()
        mac.update(data)
        return mac.digest()[:TAG_BYTES]

    def fingerprint(self) -> str:
        """A public name of the key (hex), for binding stored state to it.

        The tag of a fixed string: one-way, so it reveals nothing of the key.
        """
        return self.tag(b"ClarkLink key fingerprint").hex()

    def verify(self, data: bytes, tag: bytes) -> bool:
        """True when ``tag`` is ``data``'s tag; compared in constant time."""
        return hmac.compare_digest(self.tag(data), tag)


class ReplayWindow:
    """One sender's replay window: its highest counter and a bitmap of the 64 before it.

    A counter is fresh when it is above the highest seen, or within the 64 below
    it and not yet seen; packets that arrive out of order across a mesh within
    that span are accepted. Checking and committing are separate so that the
    codec commits only a packet that passed every other check.

    Attributes:
        highest: The highest counter accepted, or -1 before the first.
    """

    SIZE = 64
    __slots__ = ("_seen", "highest")

    def __init__(self) -> None:
        self.highest = -1
        self._seen = 0  # bit i set: counter highest - i was accepted

    def __repr__(self) -> str:
        return f"ReplayWindow(highest={self.highest}, seen=0x{self._seen:016x})"

    @classmethod
    def resumed(cls, mark: int) -> ReplayWindow:
        """A window that holds every counter up to ``mark`` as seen.

        For a receiver that restarted: ``mark`` is at or above every counter it
        accepted from the sender before (see :class:`ReplayStore`), so none of
        them is fresh again, in or below the window.
        """
        window = cls()
        window.highest = mark
        window._seen = (1 << cls.SIZE) - 1
        return window

    def is_fresh(self, counter: int) -> bool:
        """True when ``counter`` has not been accepted and is not older than the window."""
        if counter > self.highest:
            return True
        age = self.highest - counter
        return age < self.SIZE and not (self._seen >> age) & 1

    def is_duplicate(self, counter: int) -> bool:
        """True when ``counter`` was accepted and is still inside the window."""
        age = self.highest - counter
        return 0 <= age < self.SIZE and bool((self._seen >> age) & 1)

    def restart(self, counter: int) -> None:
        """Forget the window and start it again at ``counter``.

        For unauthenticated packets only: there a counter older than the window is
        a sender that restarted, or a counter garbled on the way, never a proof of
        replay (anyone can forge any counter), and refusing it would silence the
        sender until its counter caught up again.
        """
        self.highest = counter
        self._seen = 1

    def commit(self, counter: int) -> None:
        """Record ``counter`` as accepted (call only after :meth:`is_fresh` said so)."""
        if counter > self.highest:
            shift = counter - self.highest
            # Never shift by the raw distance: a 48-bit jump would build a 2**48-bit integer.
            if shift >= self.SIZE:
                self._seen = 1
            else:
                self._seen = ((self._seen << shift) | 1) & ((1 << self.SIZE) - 1)
            self.highest = counter
        else:
            self._seen |= 1 << (self.highest - counter)


class CounterStore:
    """A file holding the highest packet counter a sender may have used.

    A sender reserves counters a block at a time: it writes the end of the block
    here (atomically: temporary file, fsync, rename, fsync of the folder)
    *before* it sends with any of them. After a crash or restart it resumes
    above the stored mark, so it never reuses a counter, at the cost of skipping
    the unused rest of the last block. One store per sending agent; two codecs
    must never share a file.

    The file holds the mark as decimal digits and a newline.
    """

    def __init__(
        self, path: str | os.PathLike[str], *, block_size: int = DEFAULT_COUNTER_BLOCK
    ) -> None:
        """Name the file; nothing is read or written until :meth:`load`.

        Args:
            path: The store's file; its folder must exist.
            block_size: Counters reserved per write (see DEFAULT_COUNTER_BLOCK).
        """
        if block_size < 1:
            raise ValueError(f"block_size must be at least 1, not {block_size}")
        self.path = Path(path)
        self.block_size = block_size

    def __repr__(self) -> str:
        return f"CounterStore({str(self.path)!r}, block_size={self.block_size})"

    def load(self) -> int:
        """The stored mark: the highest counter that may have been used (0 when no file).

        Raises:
            CounterStoreError: The file cannot be read or does not hold a counter.
        """
        try:
            text = self.path.read_bytes()[:64]
        except FileNotFoundError:
            return 0
        except OSError as exc:
            raise CounterStoreError(
                f"cannot read the packet counter store: {exc.strerror}", file=str(self.path)
            ) from None
        digits = text.strip()
        if not digits.isdigit() or len(digits) > 15 or int(digits) > MAX_COUNTER:
            raise CounterStoreError(
                "the packet counter store is damaged: it must hold one whole number. Restore it, "
                "or write a number above any counter this agent has sent (its interface log has "
                "them); a smaller one makes peers drop its packets as replays",
                file=str(self.path),
            )
        return int(digits)

    def reserve(self, first: int) -> int:
        """Reserve a block of counters starting at ``first``; return the last one reserved.

        The new mark is on disk when this returns, before any counter of the
        block is used.

        Raises:
            CounterStoreError: The counters are exhausted or the file cannot be written.
        """
        if first > MAX_COUNTER:
            raise CounterStoreError(
                "the 48-bit packet counter is exhausted: generate a new mission key and "
                "delete this store",
                file=str(self.path),
            )
        last = min(first + self.block_size - 1, MAX_COUNTER)
        self._write(last)
        return last

    def _write(self, mark: int) -> None:
        try:
            _replace_file(self.path, f"{mark}\n".encode("ascii"))
        except OSError as exc:
            raise CounterStoreError(
                f"cannot write the packet counter store: {exc.strerror}", file=str(self.path)
            ) from None


def current_boot_id() -> str | None:
    """This kernel's boot id (Linux: a new random one at every boot), or None elsewhere.

    Files written without an fsync survive the crash of a process (they sit in the
    kernel's page cache), never certainly a restart of the kernel: a file that holds
    the boot id it was written under can be trusted after a crash while the id is the
    same.
    """
    try:
        text = _BOOT_ID_FILE.read_bytes()[:64].strip()
    except OSError:
        return None
    if not text or not all(33 <= c < 127 for c in text):
        return None
    return text.decode("ascii")


class ReplayStore:
    """Files holding, per sender, a mark at or above every counter a receiver accepted.

    The receiver's half of :class:`CounterStore`. Before a codec accepts an
    authenticated packet whose counter is above its sender's mark, it writes new
    marks (atomically: temporary file, rename): for that sender and every other
    it has heard, its highest accepted counter plus a reservation of what it is
    expected to send in a while (one write serves every sender, so writes
    follow time, not the sum of the rates). A reservation is measured on the
    sender's slowest recent packet interval, and is none for a sender too slow
    to send in that while: its exact mark is written with each of its packets.
    After a restart the codec starts each sender's replay window at its mark,
    so nothing accepted before the restart is accepted after it.

    Marks are kept twice, each a valid bound on its own, and a restart takes the
    lower of the two:

    * **durable** (the file at ``path``): fsynced, so it survives a power loss; it
      reserves ``durable_reserve_s`` (10 s) of each sender's traffic, so the fsyncs
      are rare;
    * **live** (``<path>.live``): not fsynced, so a write costs no wait for the disk;
      it reserves ``reserve_s`` (0.5 s) and holds the kernel's boot id. It is
      trusted only under the same boot id: after a crash of the agent's process,
      where the kernel still holds every write, whatever the crash (kill -9
      included). Without a boot id (not Linux) there is no live file, and the
      durable marks reserve ``reserve_s``, at an fsync per write.

    The cost: after a process crash a sender's packets that the receiver had never
    seen are refused for at most about ``reserve_s`` of its traffic, then accepted
    (so an agent hears a station sending once a second again at its next packet);
    after the computer's restart, about ``durable_reserve_s`` of it, counted from
    the last durable write. :meth:`~clark_engine.link.codec.Codec.save_replay_marks`
    on a clean stop writes the exact marks, and then nothing is refused but what was
    accepted.

    The files are bound to their mission and key (the first line holds the mission
    id and a fingerprint of the key, an HMAC of a constant: the key cannot be
    recovered from it): marks written under another mission or key are ignored,
    since those counters mean nothing under this one. One store per receiving
    agent; two codecs must never share its files.

    Format: ``clarklink-replay 1 <mission id> <fingerprint>`` (live:
    ``clarklink-replay-live 1 <mission id> <fingerprint> <boot id> <durable digest>``,
    the last a digest of the durable file it goes with: a live file is trusted only
    beside the durable file it was written with), then one ``<sender id> <mark>`` line
    per sender, decimal.

    Attributes:
        durable_marks: The durable file's marks, as :meth:`load` found them.
        live_marks: The live file's, when :meth:`load` could trust them; else None.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        block_size: int = DEFAULT_REPLAY_BLOCK,
        reserve_s: float = DEFAULT_REPLAY_RESERVE_S,
        durable_reserve_s: float = DEFAULT_REPLAY_DURABLE_RESERVE_S,
        boot_id: str | None = "auto",
    ) -> None:
        """Name the files; nothing is read or written until :meth:`load`.

        Args:
            path: The durable file; its folder must exist (the live file goes beside it).
            block_size: The most counters reserved per sender per write (see
                DEFAULT_REPLAY_BLOCK).
            reserve_s: How long of each sender's traffic a live write reserves (see
                DEFAULT_REPLAY_RESERVE_S); 0 writes every exact mark with each packet.
            durable_reserve_s: How long a durable write reserves (see
                DEFAULT_REPLAY_DURABLE_RESERVE_S).
            boot_id: The kernel's boot id; ``"auto"`` reads it (:func:`current_boot_id`);
                None keeps no live file. Tests pass one to play a computer's restart.
        """
        if block_size < 1:
            raise ValueError(f"block_size must be at least 1, not {block_size}")
        for name, value in (("reserve_s", reserve_s), ("durable_reserve_s", durable_reserve_s)):
            if not 0.0 <= value <= 3600.0:
                raise ValueError(f"{name} must be within 0..3600 s, not {value}")
        if boot_id == "auto":
            boot_id = current_boot_id()
        if boot_id is not None and (
            not boot_id or len(boot_id) > 64 or not all(33 <= ord(c) < 127 for c in boot_id)
        ):
            raise ValueError("boot_id must be 1 to 64 printable ASCII characters without spaces")
        self.path = Path(path)
        self.live_path = self.path.with_name(self.path.name + ".live")
        self.block_size = block_size
        self.reserve_s = reserve_s
        self.durable_reserve_s = durable_reserve_s if boot_id is not None else reserve_s
        self.boot_id = boot_id
        self.durable_marks: dict[int, int] = {}
        self.live_marks: dict[int, int] | None = None
        self._binding = ""
        self._durable_digest = _digest(b"")

    def __repr__(self) -> str:
        return (
            f"ReplayStore({str(self.path)!r}, block_size={self.block_size}, "
            f"reserve_s={self.reserve_s}, durable_reserve_s={self.durable_reserve_s}, "
            f"live={self.live})"
        )

    @property
    def live(self) -> bool:
        """True when this store keeps live marks (the kernel's boot id is known)."""
        return self.boot_id is not None

    def load(self, binding: str) -> dict[int, int]:
        """The marks to resume at, sender id -> mark: the lower of the durable and live.

        Both are at or above everything accepted under this binding, so the lower is
        too. Empty without files or under another binding. Sets
        :attr:`durable_marks` and :attr:`live_marks`.

        Args:
            binding: The mission id and key fingerprint the codec runs under; kept
                for the writes.

        Raises:
            ReplayStoreError: The durable file cannot be read or is damaged. Never
                quotes it. (A live file that cannot be read, is damaged, or was written
                under another boot is ignored: the durable marks are safe alone.)
        """
        self._binding = binding
        durable, content = self._read(self.path, f"{_REPLAY_MAGIC} {binding}")
        self.durable_marks = {} if durable is None else durable
        self._durable_digest = _digest(content)
        self.live_marks = None
        if self.boot_id is not None:
            try:
                self.live_marks, _ = self._read(self.live_path, self._live_head())
            except ReplayStoreError:
                self.live_marks = None
        marks = dict(self.durable_marks)
        for sender, mark in (self.live_marks or {}).items():
            marks[sender] = min(mark, marks.get(sender, mark))
        return marks

    def _live_head(self) -> str:
        """The live file's first line: its binding, boot and the durable file it goes with.

        The durable file's digest ties the live marks to the durable file as it was
        when they were written: if anything rewrote the durable file since (this
        store without a boot id, an engine from before live marks), the live marks
        may lag behind what was accepted, and are not trusted.
        """
        return f"{_REPLAY_LIVE_MAGIC} {self._binding} {self.boot_id} {self._durable_digest}"

    def _read(self, path: Path, head: str) -> tuple[dict[int, int] | None, bytes]:
        """One file's marks, and its content (empty without the file).

        The marks are None without the file or when its first line is not ``head``.

        Raises:
            ReplayStoreError: The file cannot be read or is damaged.
        """
        try:
            with path.open("rb") as source:
                data = source.read(_MAX_REPLAY_FILE_BYTES + 1)
        except FileNotFoundError:
            return None, b""
        except OSError as exc:
            raise ReplayStoreError(
                f"{path}: cannot read the replay store: {exc.strerror}"
            ) from None
        lines = data.split(b"\n")
        damaged = ReplayStoreError(
            f"{path}: the replay store is damaged, so this agent cannot know which "
            "packets it accepted before; restore it, or delete it only where replayed "
            "commands are harmless (say, on the ground with the mission key replaced)"
        )
        first = lines[0].split(b" ")
        magic = head.split(" ")[:2]
        if len(data) > _MAX_REPLAY_FILE_BYTES or len(lines) < 2 or lines[-1] != b"":
            raise damaged
        if [f.decode("ascii", "replace") for f in first[:2]] != magic:
            raise damaged
        if len(first) != len(head.split(" ")):
            raise damaged
        if lines[0] != head.encode("ascii"):
            return None, data  # another mission, key or boot: its counters mean nothing here
        marks: dict[int, int] = {}
        for line in lines[1:-1]:
            fields = line.split(b" ")
            if len(fields) != 2 or not all(f.isdigit() and len(f) <= 15 for f in fields):
                raise damaged
            sender, mark = int(fields[0]), int(fields[1])
            if not 1 <= sender <= 0xFFFF or mark > MAX_COUNTER or sender in marks:
                raise damaged
            marks[sender] = mark
        return marks, data

    def write(self, marks: dict[int, int]) -> None:
        """Replace both the durable and the live marks; on disk when this returns.

        Raises:
            ReplayStoreError: A file cannot be written.
        """
        self.write_durable(marks)
        self.write_live(marks)

    def write_durable(self, marks: dict[int, int]) -> None:
        """Replace the durable marks, fsynced: they survive a power loss.

        Raises:
            ReplayStoreError: The file cannot be written.
        """
        content = self._write(self.path, f"{_REPLAY_MAGIC} {self._binding}", marks, durable=True)
        self._durable_digest = _digest(content)

    def write_live(self, marks: dict[int, int]) -> None:
        """Replace the live marks, not fsynced: they survive a crash of this process.

        A no-op without a boot id.

        Raises:
            ReplayStoreError: The file cannot be written.
        """
        if self.boot_id is None:
            return
        self._write(self.live_path, self._live_head(), marks, durable=False)

    def _write(self, path: Path, head: str, marks: dict[int, int], *, durable: bool) -> bytes:
        text = "".join(f"{sender} {mark}\n" for sender, mark in sorted(marks.items()))
        content = f"{head}\n{text}".encode("ascii")
        try:
            _replace_file(path, content, durable=durable)
        except OSError as exc:
            raise ReplayStoreError(
                f"{path}: cannot write the replay store: {exc.strerror}"
            ) from None
        return content


def _digest(content: bytes) -> str:
    """A short digest of a durable replay file's content, which its live file names."""
    return hashlib.blake2b(content, digest_size=8).hexdigest()


def _replace_file(path: Path, data: bytes, *, durable: bool = True) -> None:
    """Replace ``path`` by ``data`` atomically: temporary file, (fsync,) rename.

    A crash leaves the old content or the new, never a mix. ``durable``: fsync the
    file before the rename and the folder after it, so that the new content survives
    a power loss too; without, it survives a crash of this process only.

    Raises:
        OSError: The file cannot be written (the temporary file is removed).
    """
    folder = path.parent
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as out:
            out.write(data)
            out.flush()
            if durable:
                os.fsync(out.fileno())
        os.replace(tmp, path)
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    if durable:
        _fsync_folder(folder)


def _fsync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable (POSIX; a no-op where folders cannot be opened)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass  # some file systems refuse fsync on a folder; the rename is as durable as they allow
    finally:
        os.close(fd)


def generate_key_file(path: str | os.PathLike[str]) -> None:
    """Write a new random mission key: 32 bytes as 64 hex characters and a newline.

    The file is created with mode 0600 and never overwritten: replacing a key
    silently would cut this agent off from every peer that has the old one.

    Raises:
        KeyFileError: The file already exists or cannot be written.
    """
    where = os.fspath(path)
    try:
        fd = os.open(where, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise KeyFileError(
            "already exists; refusing to overwrite a key. Delete it first if you mean to replace "
            "the key, then copy the new file to every agent",
            file=where,
        ) from None
    except OSError as exc:
        raise KeyFileError(f"cannot create the key file: {exc.strerror}", file=where) from None
    try:
        with os.fdopen(fd, "wb") as out:
            out.write(secrets.token_bytes(KEY_BYTES).hex().encode("ascii") + b"\n")
            out.flush()
            os.fsync(out.fileno())
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(where)
        raise KeyFileError(f"cannot write the key file: {exc.strerror}", file=where) from None


def load_key(path: str | os.PathLike[str]) -> bytes:
    """Read a mission key written by :func:`generate_key_file`.

    Raises:
        KeyFileError: The file is missing, readable or writable by group or
            others (fix: ``chmod 600``), not a regular file, or does not hold
            exactly 64 hex characters. The message never quotes the content.
    """
    where = os.fspath(path)
    try:
        # O_NONBLOCK: a FIFO planted at the path must not hang the agent at start-up.
        fd = os.open(where, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise KeyFileError(
            "key file not found; check key_file in the mission (relative to the mission file)",
            file=where,
        ) from None
    except OSError as exc:
        raise KeyFileError(f"cannot open the key file: {exc.strerror}", file=where) from None
    try:
        info = os.fstat(fd)  # of the open file: no race with a chmod or rename
        if not stat.S_ISREG(info.st_mode):
            raise KeyFileError("is not a regular file", file=where)
        if info.st_mode & 0o077:
            mode = stat.S_IMODE(info.st_mode)
            raise KeyFileError(
                f"key file is accessible by group or others (mode {mode:04o}); "
                f"run: chmod 600 {where}",
                file=where,
            )
        content = os.read(fd, _MAX_KEY_FILE_BYTES + 1)
    except OSError as exc:
        raise KeyFileError(f"cannot read the key file: {exc.strerror}", file=where) from None
    finally:
        os.close(fd)
    text = content.strip()
    if len(text) != 2 * KEY_BYTES or not all(c in b"0123456789abcdefABCDEF" for c in text):
        raise KeyFileError(
            f"is not a key: a key file holds {2 * KEY_BYTES} hex characters ({KEY_BYTES} bytes) "
            "and a newline; generate a new one and copy it to every agent",
            file=where,
        )
    return bytes.fromhex(text.decode("ascii"))
