"""A clip bundle's folder in the cache: its key (the clip's bytes, the options, the inference's
version), what it may hold (``WRITTEN_NAMES``), whether it is whole or damaged (set aside, never
trusted), and whether the clip changed while it was inferred."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from viewer.errors import InputError
from viewer.files.ownership import (
    discard_entry,
    file_is_ours,
    file_sha256,
    folder_lock,
    names_ours,
    set_aside,
    take_away,
    written_here,
)
from viewer.photo.bundle_version import inference_version
from viewer.photo.clip_person import PREVIEW
from viewer.photo.frames import MAX_SIZE, WORK_PERSON
from viewer.scene.clip_bundle import (
    FRAMES,
    RECORD,
    ClipFrameEntry,
    frame_name,
    read_frame_entry,
    read_record,
)


def clip_key(digest: str, options: dict, version: str) -> str:
    """What a clip bundle is made from, hashed: the clip's bytes, the options, the inference version."""
    return hashlib.sha256(f"{digest} {json.dumps(options, sort_keys=True)} {version}".encode()).hexdigest()


TEMPORAL = ("on", "off")
PEOPLE = ("one", "all")


@dataclass(frozen=True)
class ClipRequest:
    """What a clip bundle is made with (its record's ``options``): the part of the clip (``start`` to
    ``end`` seconds; None: its end), the sizes (the person's longer side in the maps, the frame's
    longer side), ``temporal`` ("on": the lighting and exposure estimated once per shot; "off": every
    frame as a photo), ``person`` (x, y as fractions of the first frame with anyone: the person to
    relight; None: the largest and most central) and ``people`` ("one": that person; "all": everyone)."""

    start: float = 0.0
    end: float | None = None
    size: int = WORK_PERSON
    max_size: int = MAX_SIZE
    temporal: str = "on"
    person: tuple | None = None
    people: str = "one"

    def options(self) -> dict:
        """The request as the record keeps it (checked: a bad ``temporal`` or ``people`` is one line)."""
        if self.temporal not in TEMPORAL:
            raise InputError(None, f"--temporal must be on or off, got {self.temporal!r}")
        if self.people not in PEOPLE:
            raise InputError(None, f"--people must be one or all, got {self.people!r}")
        return {"start": float(self.start), "end": None if self.end is None else float(self.end), "size": int(self.size),
                "max_size": int(self.max_size), "temporal": self.temporal,
                "person": None if self.person is None else [float(self.person[0]), float(self.person[1])], "people": self.people}


def cached_clip_path(clip_path, folder, request: ClipRequest, digest: str | None = None) -> Path:
    """Where the cache keeps the clip bundle of ``clip_path`` made with ``request`` (in ``folder``);
    ``digest``: the clip's SHA-256 when already known."""
    key = clip_key(digest or file_sha256(clip_path), request.options(), inference_version())
    return Path(folder) / f"{Path(clip_path).stem}-clip-{key[:16]}"


def clip_target(out_dir) -> Path:
    """``out_dir`` as a place for a clip bundle: new, empty, or one this program wrote (its record
    marked as ours, and nothing in it but the record and the frames' folder). Anything else is
    refused in one line."""
    out_dir = Path(out_dir).resolve()
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(out_dir, "exists and is not a folder: give a folder for the clip bundle")
    if out_dir.is_dir() and any(out_dir.iterdir()):
        names = {p.name for p in out_dir.iterdir()}
        if not file_is_ours(out_dir / RECORD) or not names <= WRITTEN_NAMES:
            raise InputError(out_dir, "is a folder with files relight did not write there: give a new or empty folder for "
                                      "the clip bundle (nothing was written)")
    return out_dir


def frames_ours(frames: Path, exactly: bool = True) -> bool:
    """Whether everything in a clip bundle's ``frames`` folder is what this program wrote there: ``exactly`` as it
    wrote it (each record's mark, each frame's bundle as its marker lists it), else by name only (a frame's file cut
    short still counts: :func:`viewer.files.ownership.names_ours`). No link counts."""
    for p in frames.iterdir():
        if p.name.startswith("."):  # a frame's bundle being written when a run stopped (fresh_sibling's names)
            continue
        if p.suffix in (".json", ".png") and p.stem.isdigit():
            ours = file_is_ours(p) if exactly else p.is_file() and not p.is_symlink()
        else:
            ours = p.name.isdigit() and (written_here(p) if exactly else names_ours(p))
        if not ours:
            return False
    return True


def start_over(out_dir: Path) -> None:
    """Take away an earlier clip bundle of this program's in ``out_dir`` (another clip or options)."""
    frames = out_dir / FRAMES
    if frames.is_dir():
        if not frames_ours(frames):
            raise InputError(frames, "holds files relight did not write: give a new or empty folder for the clip bundle")
        take_away(frames)
    (out_dir / RECORD).unlink(missing_ok=True)


def finished_frame(frames: Path, index: int) -> ClipFrameEntry | None:
    """Frame ``index``'s record when the frame is whole (its record ours, its bundle whole), else None."""
    record = frames / f"{frame_name(index)}.json"
    if not file_is_ours(record):
        return None
    try:
        entry = read_frame_entry(record)
    except InputError:
        return None
    if entry.index != index or (entry.state == "person" and not written_here(frames / frame_name(index))):
        return None
    return entry


BUSY = "another relight is making this clip bundle now: run again when it is done"


def entry_problem(out_dir: Path) -> str | None:
    """What does not check out in the cache's clip bundle ``out_dir`` (None: whole so far, or absent): a link, a
    file this program did not write there, a record that does not parse or is not its own, a frame's record or
    files that are not as it wrote them."""
    if out_dir.is_symlink():
        return "it is a link"
    if not out_dir.exists():
        return None
    if not out_dir.is_dir():
        return "it is not a folder"
    names = {p.name for p in out_dir.iterdir()}
    if not names:
        return None
    if not names <= WRITTEN_NAMES:
        return f"it holds {sorted(names - WRITTEN_NAMES)[0]!r}, which relight does not write there"
    if (out_dir / RECORD).is_symlink() or not file_is_ours(out_dir / RECORD):
        return f"its {RECORD} is not one relight wrote"
    try:
        read_record(out_dir)
    except InputError as exc:
        return f"its record does not check out ({exc.problem})"
    frames = out_dir / FRAMES
    if frames.is_symlink() or (frames.exists() and not frames.is_dir()):
        return f"its {FRAMES} is a link or not a folder"
    if frames.is_dir():
        if not frames_ours(frames):
            return "a frame's files are not as relight wrote them"
        for p in frames.glob("*.json"):
            try:
                read_frame_entry(p)
            except InputError as exc:
                return f"frame {p.stem}'s record does not check out ({exc.problem})"
    return None


def entry_names_ours(out_dir: Path) -> bool:
    """Whether the clip bundle ``out_dir`` holds only what this program writes there, by name (its files' bytes may
    have changed: a frame's map cut short): no link anywhere, no name it does not write."""
    if out_dir.is_symlink() or not out_dir.is_dir() or not {p.name for p in out_dir.iterdir()} <= WRITTEN_NAMES:
        return False
    if any(p.is_symlink() for p in (out_dir / RECORD, out_dir / PREVIEW)) or (out_dir / FRAMES).is_symlink():
        return False
    return not (out_dir / FRAMES).is_dir() or frames_ours(out_dir / FRAMES, exactly=False)


def set_aside_if_damaged(out_dir: Path) -> str | None:
    """The cache's clip bundle ``out_dir`` out of the way when something in it does not check out
    (:func:`entry_problem`), so that it is made again: removed when it holds only what this program wrote there, else
    moved aside, renamed beside it (``.NAME.damaged-TIME-...``: a user's file or a link in it is never removed,
    :func:`viewer.files.ownership.discard_entry`); the note that says so (None: nothing done). A bundle another run
    is making now (its lock held) is left to that run."""
    problem = entry_problem(out_dir)
    if problem is None:
        return None
    if not out_dir.is_symlink() and out_dir.is_dir():
        try:
            with folder_lock(out_dir, busy=BUSY):
                aside = discard_entry(out_dir, entry_names_ours(out_dir))
        except InputError:
            return None
    else:
        aside = set_aside(out_dir)
    where = f"moved aside to {aside.name}" if aside is not None else "removed"
    return f"{out_dir}: the cached clip bundle did not check out ({problem}): {where}, the clip is inferred again"


def source_state(path) -> tuple:
    """What says a file changed: its device, inode, size and times (a file written over and put back has a new
    change time, even with its old bytes and modification time)."""
    st = Path(path).stat()
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns


def unchanged(clip_path, before: tuple, out_dir: Path) -> None:
    """The clip bundle in ``out_dir``, made from ``clip_path`` while it was as ``before`` (:func:`source_state`),
    taken away and one line when the clip changed meanwhile: frames decoded from a clip being written over would
    be served as the clip's."""
    try:
        now = source_state(clip_path)
    except OSError:
        now = None
    if now != before:
        (out_dir / RECORD).unlink(missing_ok=True)  # first: stopped while the frames go, nothing claims to be whole
        start_over(out_dir)
        (out_dir / PREVIEW).unlink(missing_ok=True)
        raise InputError(clip_path, "changed while it was being inferred (written over, moved or touched): its bundle was "
                                    "not kept; run again once it is in place")


WRITTEN_NAMES = frozenset({RECORD, FRAMES, PREVIEW})  # all a clip bundle's folder holds
