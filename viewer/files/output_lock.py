"""One writer per output: an exclusive lock held for a whole run.

``relight render`` and a batch take :class:`ExclusiveLock` on what they write before any work: a hidden lock file
beside the output (:func:`lock_path`: ``.out.mp4.relight-lock``; a batch's is its folder's ``.relight-batch.lock``),
held with ``flock``, which the kernel drops when the process ends however it ends (SIGKILL too), so a lock left by a
dead run is taken over by the next. A second run on the same output is refused at once in one line that names the
holder (its process, since when; the lock file records its command too), never left to mix its frames or parts
with the first's. (A window's recordings take no lock: their names are new each time, their partial file made
exclusively.)

The lock file records the run (JSON: ``relight-lock``, the process, the command, when) and the partial files it has
made (:func:`create_partial`: a video's ``name.partial.mp4``, by device and inode). A run that takes over from a
dead one removes the partial files that run recorded, where the same file is still there (its inode unchanged): they
are this program's, cut short, and the run makes them again; any other file at a partial's name is the user's and is
refused as before. The lock file is removed when the run ends (an output's; a batch folder's stays, as its
manifest does); removed, a waiting taker's descriptor may hold the old file, so a taker checks that the name still
names the file it locked and tries again when not (the usual flock-and-unlink protocol).

Why flock and a file beside the output, not the output folder's lock: renders of two outputs in one folder go on
side by side; a PID file alone is not enough (a PID is reused, and a killed run leaves it).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
import sys
import time
from pathlib import Path

from viewer.errors import InputError

SUFFIX = ".relight-lock"
FORMAT = "relight-lock"
NAME_MAX = 255
RECORD_MAX = 1 << 16  # bytes: a lock file longer than this is not one this program wrote
HOLDER_WAITS = 20  # 50-ms waits for a holder that has just taken the lock to write who it is


def lock_path(output) -> Path:
    """The lock file of ``output``: ``.NAME.relight-lock`` beside it (a name too long for that: a hash of it)."""
    output = Path(output)
    name = f".{output.name}{SUFFIX}"
    if len(os.fsencode(name)) > NAME_MAX:
        name = f".{hashlib.sha256(os.fsencode(output.name)).hexdigest()[:32]}{SUFFIX}"
    return output.with_name(name)


class ExclusiveLock:
    """Held while a run writes ``output`` (a context manager). ``path``: the lock file (default
    :func:`lock_path`); ``remove``: remove it when done (an output's; a folder's stays); ``busy``: the refusal's words
    after the holder's description."""

    def __init__(self, output, path=None, remove: bool = True,
                 busy: str = "wait for it to finish, or choose another -o"):
        self.output = Path(output)
        self.path = Path(path) if path is not None else lock_path(self.output)
        self.remove = remove
        self.busy = busy
        self._fd: int | None = None
        self._made: list[Path] = []

    def __enter__(self) -> ExclusiveLock:
        import fcntl

        self._made_folders()
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
            except OSError as exc:  # a link, a folder, a name the system refuses
                self._unmake_folders()
                raise InputError(self.path, f"cannot hold the lock of {self.output.name} here ({exc.strerror or exc})") from None
            if not stat.S_ISREG(os.fstat(fd).st_mode):  # a pipe or a device at the lock's name
                os.close(fd)
                self._unmake_folders()
                raise InputError(self.path, f"is not a file (a pipe or a device): cannot hold the lock of {self.output.name} here")
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                record = _read(fd)
                for _ in range(HOLDER_WAITS):  # the holder has the lock and is writing its record now
                    if record:
                        break
                    time.sleep(0.05)
                    record = _read(fd)
                holder = _holder(record)
                os.close(fd)
                self._unmake_folders()
                raise InputError(self.output, f"is being written by another relight ({holder}): {self.busy}") from None
            if _same_file(fd, self.path):
                break
            os.close(fd)  # the holder before removed the file we locked: the name's file now is another
        self._fd = fd
        try:
            earlier = _read(fd)
            if earlier is None:  # bytes that are no lock record of this program's: left as they were
                raise InputError(self.path, "is not a lock file relight wrote: move it away")
            self._take_over(earlier)
            record = {"format": FORMAT, "process": os.getpid(), "command": " ".join(sys.argv[1:])[:300],
                      "since": time.strftime("%Y-%m-%d %H:%M:%S"), "partials": {}}
            _write(fd, record)
        except BaseException:
            self._release(remove=False)
            raise
        return self

    def __exit__(self, *exc) -> None:
        self._release(self.remove)

    def _take_over(self, earlier: dict) -> None:
        """What a dead run left beside the output removed: the partial files it recorded, where each is still the
        file it made (the same inode, beside the output and named after it, empty or an MP4: an inode freed and
        taken by a user's new file is no MP4), and its temporary files and folders (named after the output, with
        its process number: :func:`viewer.files.imageio.atomic_paths`' ``.NAME.PID.tmp``,
        :func:`viewer.files.ownership.fresh_sibling`'s ``.NAME.TAG.PID.HEX``)."""
        import shutil

        folder, stem = self.output.absolute().parent, self.output.stem
        named = re.compile(rf"^\.?{re.escape(stem)}[._]")
        for name, ident in (earlier.get("partials") or {}).items():
            p = Path(name)
            if not (isinstance(ident, list) and p.parent == folder and named.match(p.name)):
                continue
            try:
                st = os.stat(p, follow_symlinks=False)
                if [st.st_dev, st.st_ino] == ident and stat.S_ISREG(st.st_mode) and _empty_or_mp4(p, st):
                    p.unlink()
            except OSError:
                continue
        process = earlier.get("process")
        if not isinstance(process, int) or isinstance(process, bool):
            return
        temporary = re.compile(rf"^\.+{re.escape(stem)}[._].*\.{process}\.(tmp|[0-9a-f]{{8}})$")
        for entry in os.scandir(folder):
            if temporary.match(entry.name):
                if entry.is_dir(follow_symlinks=False):
                    shutil.rmtree(entry.path, ignore_errors=True)
                elif entry.is_file(follow_symlinks=False):
                    os.unlink(entry.path)

    def _release(self, remove: bool) -> None:
        if self._fd is None:
            return
        if remove:
            try:
                if _same_file(self._fd, self.path):
                    os.unlink(self.path)
            except OSError:
                pass
        os.close(self._fd)  # closing drops the flock
        self._fd = None
        if remove:
            self._unmake_folders()

    def _made_folders(self) -> None:
        """The lock's folder made where missing (the folders made are removed again when left empty)."""
        missing, p = [], self.path.parent.absolute()
        while not p.exists() and p != p.parent:
            missing.append(p)
            p = p.parent
        for folder in reversed(missing):
            try:
                folder.mkdir()
                self._made.append(folder)
            except FileExistsError:
                pass
            except OSError as exc:
                raise InputError(folder, f"cannot be made ({exc.strerror or exc})") from None

    def _unmake_folders(self) -> None:
        for folder in reversed(self._made):
            try:
                folder.rmdir()  # only when empty: what the run wrote there stays
            except OSError:
                break
        self._made = []


def held_now(output) -> bool:
    """Whether a run holds ``output``'s lock now (a batch leaves that output's temporary files alone)."""
    import fcntl

    try:
        fd = os.open(lock_path(output), os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC | os.O_NONBLOCK)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        return False
    except BlockingIOError:
        return True
    except OSError:
        return False
    finally:
        os.close(fd)  # (a shared lock taken here is dropped with it)


def create_partial(partial, output) -> None:
    """Create the empty file ``partial`` (a video's ``NAME.partial.mp4``, written for ``output``) exclusively
    (``FileExistsError`` when anything is there), recorded in ``output``'s lock where this process holds it, so that
    a run after a crash removes it (:class:`ExclusiveLock`). With no lock of this process's (a writer used on its
    own) it is only created.

    There is no moment at which the file exists and is not recorded: it is made under a name of its own, recorded
    under both names by its inode, then linked to ``partial`` (a link fails when the name is taken, as an exclusive
    create does) and its own name removed; killed at any step, what is left is recorded."""
    import secrets

    partial = Path(partial)
    held = _held(output)
    if held is None:
        os.close(os.open(partial, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
        return
    fd, record = held
    try:
        own = partial.with_name(f".{partial.name}.{os.getpid()}.{secrets.token_hex(4)}")
        os.close(os.open(own, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
        st = os.stat(own, follow_symlinks=False)
        partials = record.setdefault("partials", {})
        for name in (own, partial):
            partials[str(name.absolute())] = [st.st_dev, st.st_ino]
        _write(fd, record)
        try:
            os.link(own, partial)
        except FileExistsError:
            raise
        except OSError:  # a file system without hard links: the name checked, then taken by a rename
            if partial.exists() or partial.is_symlink():
                raise FileExistsError(partial) from None
            os.rename(own, partial)
        finally:
            own.unlink(missing_ok=True)
    finally:
        os.close(fd)


def _held(output) -> tuple[int, dict] | None:
    """(a descriptor of ``output``'s lock file, its record) when this process holds that lock, else None."""
    try:
        fd = os.open(lock_path(output), os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return None
    record = _read(fd)
    if not record or record.get("process") != os.getpid():
        os.close(fd)
        return None
    return fd, record


def _write(fd: int, record: dict) -> None:
    data = json.dumps(record).encode()
    os.ftruncate(fd, 0)
    os.pwrite(fd, data, 0)


def _empty_or_mp4(path: Path, st) -> bool:
    """Whether a file is empty or begins as an MP4 does (its first box an ``ftyp``)."""
    if st.st_size == 0:
        return True
    with open(path, "rb") as f:
        return f.read(8)[4:8] == b"ftyp"


def _same_file(fd: int, path: Path) -> bool:
    try:
        st, now = os.fstat(fd), os.stat(path, follow_symlinks=False)
    except OSError:
        return False
    return (st.st_dev, st.st_ino) == (now.st_dev, now.st_ino)


def _read(fd: int) -> dict | None:
    """The lock file's record: {} when empty (just made), None when it holds what this program does not write."""
    data = os.pread(fd, RECORD_MAX + 1, 0)
    if not data.strip() or (data.startswith(b"process ") and len(data) < 200):  # just made, or an older batch lock's line
        return {}
    try:
        record = json.loads(data.decode())
    except (UnicodeDecodeError, ValueError, RecursionError):
        return None
    return record if isinstance(record, dict) and record.get("format") == FORMAT and len(data) <= RECORD_MAX else None


def _holder(record: dict | None) -> str:
    """The holder in words, from its record."""
    if not record:
        return "its process not yet known"
    process, since = record.get("process"), record.get("since")
    words = f"process {process}" if isinstance(process, int) else "a process"
    return words + (f", since {since[:19]}" if isinstance(since, str) else "")
