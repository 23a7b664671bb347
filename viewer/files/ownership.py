"""What this program wrote, so that it replaces only that.

A file it writes carries its mark inside (``viewer.files.imageio.MARK``: a PNG text chunk, a JPEG comment, an EXR header
attribute, a JSON field, an MP4's metadata), so rendering again to the same ``-o`` replaces its own files,
while any other file at an output path, the one named or one written beside it, is refused in one line
unless the user says ``--force`` (:func:`refuse_foreign`). A folder it writes (a scene bundle) carries a
marker, ``.relight-written.json``, listing every file it holds with its SHA-256 and a hash of that list.
A folder is replaced only when its marker is intact and it holds exactly the files listed, unchanged: a
user's ``thesis.txt`` beside a ``scene.json``, a note added to an earlier bundle, or an edited map make it
the user's, and it is refused in one line. Temporary folders get names no other process and no user file
can have (created exclusively), and the final swap into place holds a lock on the parent folder, so two
writers to one output take turns instead of mixing their files.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import secrets
from pathlib import Path

from viewer.files.imageio import MARK, MARK_TEXT, ffmpeg_file, read_json

MARKER = ".relight-written.json"
FORMAT = "relight-written"
CHUNK = 1 << 20


def file_sha256(path) -> str:
    """SHA-256 of a file's bytes, read in chunks (a clip or a map can be large)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(CHUNK), b""):
            h.update(block)
    return h.hexdigest()


def _list_hash(files: dict) -> str:
    return hashlib.sha256(json.dumps(files, sort_keys=True).encode()).hexdigest()


def _contents(folder: Path) -> dict | None:
    """name -> SHA-256 of every regular file directly in ``folder`` (the marker left out); None when
    it holds anything else (a sub-folder, a link, a device)."""
    files = {}
    for entry in os.scandir(folder):
        if entry.name == MARKER:
            continue
        if not entry.is_file(follow_symlinks=False):
            return None
        files[entry.name] = file_sha256(Path(entry.path))
    return files


def mark_written(folder) -> None:
    """Record ``folder``'s files as this program's (call once everything is written in it)."""
    folder = Path(folder)
    files = _contents(folder)
    if files is None:
        raise OSError(f"{folder}: holds something other than files; not marked")
    data = {"format": FORMAT, "files": files, "hash": _list_hash(files)}
    (folder / MARKER).write_text(json.dumps(data, indent=1) + "\n")


def _marked(folder: Path) -> dict | None:
    """The files ``folder``'s marker lists (name -> SHA-256), when it is a real folder with an intact marker; else None."""
    marker = folder / MARKER
    if folder.is_symlink() or not folder.is_dir() or marker.is_symlink() or not marker.is_file():
        return None
    try:
        data = json.loads(marker.read_text())
        files = data["files"]
    except (OSError, ValueError, KeyError, TypeError, RecursionError):
        return None
    if data.get("format") != FORMAT or not isinstance(files, dict) or data.get("hash") != _list_hash(files):
        return None
    return files


def written_here(folder) -> bool:
    """Whether ``folder`` is a folder this program wrote, exactly as it wrote it."""
    files = _marked(Path(folder))
    try:
        return files is not None and _contents(Path(folder)) == files
    except OSError:
        return False


def fresh_sibling(path, tag: str) -> Path:
    """A new, empty folder beside ``path`` with a name no one else has (created here, exclusively)."""
    path = Path(path)
    while True:
        candidate = path.with_name(f".{path.name}.{tag}.{os.getpid()}.{secrets.token_hex(4)}")
        try:
            candidate.mkdir()
            return candidate
        except FileExistsError:
            continue


def take_away(path, tag: str = "old") -> None:
    """Remove ``path`` (a folder this program wrote; the caller has checked): first moved aside under a
    name no one else has, so that the name is free at once and a removal cut short leaves no half
    folder under it."""
    import shutil

    aside = fresh_sibling(path, tag)
    Path(path).rename(aside / Path(path).name)
    shutil.rmtree(aside, ignore_errors=True)


def names_ours(folder) -> bool:
    """Whether ``folder`` holds only files this program wrote there, by name (their bytes may have changed since:
    a file cut short, one deleted): a real folder whose marker is intact and lists every regular file in it."""
    files = _marked(Path(folder))
    try:
        return files is not None and all(e.name == MARKER or (e.is_file(follow_symlinks=False) and e.name in files)
                                         for e in os.scandir(folder))
    except OSError:
        return False


def discard_entry(path, ours: bool) -> Path | None:
    """A cache's entry that does not check out, out of the way so that it is made again: removed (:func:`take_away`)
    when it holds only what this program wrote there (``ours``, the caller's judgement by name: a file of it cut
    short or deleted), else moved aside (:func:`set_aside`: a user's file or a link in it is never removed).
    Returns where it was moved, None when removed."""
    if ours:
        take_away(path, "damaged")
        return None
    return set_aside(path)


def set_aside(path) -> Path:
    """Move ``path`` (a cache's entry that does not check out) aside, renamed beside it as ``.NAME.damaged-TIME-PID``:
    nothing in it is removed (a user's file put there included); returns where it went."""
    import time

    path = Path(path)
    aside = path.with_name(f".{path.name}.damaged-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}-{secrets.token_hex(2)}")
    path.rename(aside)
    return aside


@contextlib.contextmanager
def folder_lock(folder, busy: str | None = None):
    """An exclusive lock on ``folder`` (flock on its descriptor) for the duration: writers into it
    take turns; nothing is created in it. ``busy``: do not wait for another holder; refuse with this
    line, naming the folder."""
    import fcntl

    from viewer.errors import InputError

    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | (fcntl.LOCK_NB if busy else 0))
        except BlockingIOError:
            raise InputError(folder, busy) from None
        yield
    finally:
        os.close(fd)  # closing releases the lock


def file_is_ours(path) -> bool:
    """Whether the file at ``path`` carries this program's mark (anything unreadable does not)."""
    path = Path(path)
    if path.is_symlink() or not path.is_file():
        return False
    key, value = MARK
    suffix = path.suffix.lower()
    try:
        if suffix in (".png", ".jpg", ".jpeg"):
            from PIL import Image

            with Image.open(path) as im:
                if suffix == ".png":
                    return getattr(im, "text", {}).get(key) == value
                return im.info.get("comment") == MARK_TEXT.encode()
        if suffix == ".exr":
            import OpenEXR

            return OpenEXR.File(str(path), header_only=True).header().get(key) == value
        if suffix == ".json":
            data = read_json(path)
            return isinstance(data, dict) and data.get(key) == value
        if suffix in (".mp4", ".mov", ".m4v", ".mkv", ".webm", ".avi"):  # a video, or a relit clip's audio beside it
            import av

            with av.open(ffmpeg_file(path)) as container:
                return container.metadata.get("comment") == MARK_TEXT
    except Exception:  # noqa: BLE001 -- a file it cannot read as its own is not its own
        return False
    return False


def refuse_foreign(paths, force: bool = False) -> None:
    """Before any work: every path of ``paths`` that holds a file this program did not write (no
    ``MARK`` in it) is refused in one line naming it, unless ``force``."""
    from viewer.errors import InputError

    for p in paths:
        p = Path(p)
        if (p.exists() or p.is_symlink()) and not force and not file_is_ours(p):
            raise InputError(p, "is not a file relight wrote: refusing to replace it (move it away, choose another -o, "
                                "or give --force to replace it)")
