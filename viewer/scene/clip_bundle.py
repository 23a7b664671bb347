"""The clip bundle: what ``relight infer CLIP`` writes, one scene bundle per frame (docs/scene-bundle.md).

=========================  ====================================================================
clip.json                  {"format": "relight-clip", "version": 1, "source": the clip (path,
                           SHA-256 of its bytes, size, rotation, rate, frames, audio codec),
                           "options": the range and sizes it was inferred with, "key": what
                           those hash to, "temporal": "off"; once every frame is in, "complete":
                           true, "frames" (the count), "states" (frames per state) and
                           "first_frame_at" (the first frame's time on the clip's clock, which
                           its audio shares); inferred in ranges: "shot_starts", "ranges",
                           "pan_offsets" (:mod:`viewer.photo.clip_ranges`)}
frames/NNNNNN.json         frame N (from 0, in time order): "seconds" from the first frame, and
                           "state": "person" (its scene bundle beside it), "no person" (the new
                           background alone is shown) or "lost" (a damaged packet: the frame
                           before it is shown); "shot", "pan" and "pan_from" (ClipFrameEntry)
frames/NNNNNN/             frame N's scene bundle, exactly as ``relight infer`` writes a photo's
frames/NNNNNN.png          a frame with no person: the frame itself at the output size (what a
                           ``--background photo`` shows there)
=========================  ====================================================================

Each frame's bundle and record are written whole or not at all, the record after the bundle, so
a run that stops keeps every frame it finished (:mod:`viewer.photo.clip_inference` goes on from
there). Reading a clip bundle lists its frames; a frame's scene is loaded when it is needed.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import MARK, read_json

FORMAT = "relight-clip"
VERSION = 2  # 2: frame records may count their pan from a range's first frame (pan_from, the record's pan_offsets)
RECORD = "clip.json"
FRAMES = "frames"
STATES = ("person", "no person", "lost")


def frame_name(index: int) -> str:
    return f"{index:06d}"


@dataclass(frozen=True)
class ClipFrameEntry:
    """One frame of a clip bundle: its ``index``, time in ``seconds``, ``state`` (``STATES``), the
    ``shot`` it is in (0, 1, ... : what is estimated once per shot is estimated again after a cut) and
    ``pan``: how far (x, y) the old background moved since the shot's first frame, in output pixels
    (the camera's turn, :mod:`viewer.photo.camera_motion`); ``pan_from``: None, or the frame the pan
    was counted from instead, by a worker that inferred a range of the clip begun within the shot
    (the record's ``pan_offsets`` then holds what the shot's pan was at that frame, added on reading)."""

    index: int
    seconds: float
    state: str
    note: str = ""
    shot: int = 0
    pan: tuple[float, float] = (0.0, 0.0)
    pan_from: int | None = None

    def to_json(self) -> dict:
        return {"index": self.index, "seconds": round(self.seconds, 6), "state": self.state, "note": self.note, "shot": self.shot,
                "pan": [round(float(v), 4) for v in self.pan], **({"pan_from": self.pan_from} if self.pan_from is not None else {}),
                MARK[0]: MARK[1]}


@dataclass(frozen=True)
class ClipBundle:
    """A whole clip bundle: its folder, its record (``clip.json``) and its frames in time order."""

    path: Path
    record: dict
    frames: tuple[ClipFrameEntry, ...]

    def scene_path(self, index: int) -> Path:
        return self.path / FRAMES / frame_name(index)

    @property
    def temporal(self) -> bool:
        """Whether the clip was inferred as a clip (one light and exposure per shot), not frame by frame."""
        return self.record.get("temporal") == "on"

    @property
    def source(self) -> dict:
        return self.record["source"]

    @property
    def duration(self) -> float:
        """Seconds from the first frame to the end of the last (one frame interval past its start)."""
        fps = float(self.source.get("fps") or 30.0)
        return (self.frames[-1].seconds if self.frames else 0.0) + 1.0 / fps


def is_clip_bundle(path) -> bool:
    return (Path(path) / RECORD).is_file()


MAX_SECONDS = 1e6  # a clip's times past this (11 days) are no clip's
ROTATIONS = (0, 90, 180, 270)


def read_record(path) -> dict:
    """``clip.json`` of the clip bundle at ``path``, checked field by field before any work (:func:`check_record`)."""
    path = Path(path)
    if path.is_symlink():
        raise InputError(path, "is a link: a clip bundle is read only where it is (give the folder itself)")
    record_path = path / RECORD
    if record_path.is_symlink():
        raise InputError(record_path, "is a link: a clip bundle's files are read only inside it")
    record = read_json(record_path, "clip bundle record")
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise InputError(record_path, f"not a clip bundle record (format {FORMAT!r} expected)")
    check_record(record, record_path)
    return record


def _number(value, lo: float = -MAX_SECONDS, hi: float = MAX_SECONDS, whole: bool = False) -> bool:
    """Whether ``value`` is a JSON number (not a boolean) in [lo, hi] (``whole``: an integer)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (whole and not isinstance(value, int)):
        return False
    return bool(np.isfinite(value)) and lo <= value <= hi


def check_record(record: dict, where: Path) -> None:
    """Every field of a clip bundle's record for its type, range and consistency: one line naming
    ``where`` and the field for the first that does not check out."""
    def bad(field: str, want: str):
        raise InputError(where, f"{field} must be {want}, got {str(record_get(field))[:60]!r}")

    def record_get(field: str):
        value = record
        for part in field.split("."):
            value = value.get(part) if isinstance(value, dict) else None
        return value

    version = record.get("version")
    if not _number(version, 1, VERSION, whole=True):
        raise InputError(where, f"version {str(version)[:20]!r} is not one this program reads (1 to {VERSION})")
    source = record.get("source")
    if not isinstance(source, dict):
        raise InputError(where, "has no source clip")
    if not isinstance(source.get("path"), str) or not source["path"]:
        bad("source.path", "the clip's path")
    if not (isinstance(source.get("sha256"), str) and len(source["sha256"]) == 64):
        bad("source.sha256", "the clip's SHA-256 (64 hex digits)")
    for field in ("width", "height"):
        if not _number(source.get(field), 1, 1 << 16, whole=True):
            bad(f"source.{field}", "a whole number of pixels from 1 to 65536")
    if not _number(source.get("fps"), 1e-3, 1e4):
        bad("source.fps", "frames a second, a positive number up to 10000")
    if source.get("rotation", 0) not in ROTATIONS:
        bad("source.rotation", "0, 90, 180 or 270")
    if not _number(source.get("duration", 0.0), 0.0):
        bad("source.duration", "seconds, 0 or more")
    if not _number(source.get("frames", 0), 0, 1 << 31, whole=True):
        bad("source.frames", "a whole number of frames")
    if source.get("audio") is not None and not isinstance(source["audio"], str):
        bad("source.audio", "a codec's name or null")
    options = record.get("options")
    if not isinstance(options, dict):
        raise InputError(where, "has no options (the part of the clip and the sizes it was inferred with)")
    if not _number(options.get("start", 0.0), 0.0):
        bad("options.start", "seconds, 0 or more")
    if options.get("end") is not None and not (_number(options["end"], 0.0) and options["end"] > options.get("start", 0.0)):
        bad("options.end", "null or seconds after options.start")
    for field in ("size", "max_size"):
        if field in options and not _number(options[field], 1, 1 << 16, whole=True):
            bad(f"options.{field}", "a whole number of pixels")
    if record.get("temporal", "off") not in ("on", "off"):
        bad("temporal", "on or off")
    if not isinstance(record.get("complete", False), bool):
        bad("complete", "true or false")
    if record.get("complete"):
        if not _number(record.get("frames"), 1, 1 << 31, whole=True):
            bad("frames", "the count of frames, 1 or more")
        if not _number(record.get("first_frame_at", 0.0)):
            bad("first_frame_at", f"the first frame's time on the clip's clock, within {MAX_SECONDS:g} s of its origin")
        states = record.get("states")
        if states is not None and not (isinstance(states, dict) and all(_number(v, 0, record["frames"], whole=True)
                                                                          for v in states.values())):
            bad("states", "frames per state")
        if record.get("shots") is not None and not _number(record["shots"], 0, record["frames"], whole=True):
            bad("shots", "null or the count of shots")
        if not (isinstance(record.get("gaps", []), list) and all(isinstance(g, str) for g in record.get("gaps", []))):
            bad("gaps", "a list of lines")
    if not _number(record.get("expected_frames", 0), 0, 1 << 31, whole=True):
        bad("expected_frames", "a whole number of frames")
    person = record.get("person")
    if person is not None:
        box = person.get("box") if isinstance(person, dict) else None
        if not (isinstance(box, list) and len(box) == 4 and all(_number(v, -1.0, 2.0) for v in box)):
            bad("person.box", "the person's box: four numbers, fractions of the frame")
        last = record["frames"] - 1 if record.get("complete") else 1 << 31
        if not _number(person.get("frame"), 0, last, whole=True):
            bad("person.frame", "the frame the person was chosen on, one of the clip's")


MAX_PAN = 1e6  # output pixels: a camera's turn past this is no clip's


def read_frame_entry(path: Path) -> ClipFrameEntry:
    """A frame's record (``frames/NNNNNN.json``), every field checked for its type and range: one line naming the
    file and the field."""
    data = read_json(path, "clip frame record")
    if not isinstance(data, dict) or not all(k in data for k in ("index", "seconds", "state")):
        raise InputError(path, "is not a clip frame record (an object with index, seconds, state)")

    def bad(field: str, want: str):
        raise InputError(path, f"{field} must be {want}, got {str(data.get(field))[:40]!r}")

    if not _number(data["index"], 0, 1 << 31, whole=True):
        bad("index", "the frame's number, 0 or more")
    if not _number(data["seconds"]):
        bad("seconds", f"the frame's time, a number within {MAX_SECONDS:g} s")
    if data["state"] not in STATES:
        bad("state", f"one of {', '.join(STATES)}")
    if not isinstance(data.get("note", ""), str):
        bad("note", "text")
    if not _number(data.get("shot", 0), 0, data["index"], whole=True):
        bad("shot", "the shot's number, from 0 to the frame's")
    pan = data.get("pan", [0.0, 0.0])
    if not (isinstance(pan, list) and len(pan) == 2 and all(_number(v, -MAX_PAN, MAX_PAN) for v in pan)):
        bad("pan", f"two numbers of pixels within {MAX_PAN:g}")
    pan_from = data.get("pan_from")
    if pan_from is not None and not _number(pan_from, 0, data["index"], whole=True):
        bad("pan_from", "null or a frame before this one")
    return ClipFrameEntry(data["index"], float(data["seconds"]), data["state"], data.get("note", ""), data.get("shot", 0),
                          (float(pan[0]), float(pan[1])), pan_from)


def absolute_pan(entry: ClipFrameEntry, record: dict, path: Path) -> ClipFrameEntry:
    """``entry`` with its pan counted from its shot's first frame (``pan_from`` resolved by the record's
    ``pan_offsets``: a clip inferred in ranges, :mod:`viewer.photo.clip_ranges`)."""
    if entry.pan_from is None:
        return entry
    offset = record.get("pan_offsets", {}).get(str(entry.pan_from))
    if not (isinstance(offset, list) and len(offset) == 2 and all(isinstance(v, (int, float)) and np.isfinite(v) for v in offset)):
        raise InputError(path / RECORD, f"has no pan for frame {entry.pan_from} (frame {entry.index}'s pan counts from it)")
    return replace(entry, pan=(entry.pan[0] + float(offset[0]), entry.pan[1] + float(offset[1])), pan_from=None)


def load_clip_bundle(path) -> ClipBundle:
    """The clip bundle at ``path``; one line when it is not one, or not complete (a run that
    stopped: run ``relight infer`` again to finish it)."""
    path = Path(path)
    record = read_record(path)
    if not record.get("complete"):
        raise InputError(path, "is a clip bundle not finished yet (its inference stopped): run the same `relight infer` "
                               "again to go on from its last frame")
    count = record["frames"]
    folder = path / FRAMES
    if folder.is_symlink() or not folder.is_dir():
        raise InputError(folder, "is a link or missing: a clip bundle's frames are read only inside it")
    on_disk = sum(1 for p in folder.iterdir() if p.suffix == ".json" and p.stem.isdigit())
    if on_disk != count:
        raise InputError(path / RECORD, f"frames says {count}, the bundle holds {on_disk} frame records: its record and "
                                        "its frames do not agree (infer the clip again)")
    frames, before = [], None
    for i in range(count):
        entry_path = folder / f"{frame_name(i)}.json"
        for linked in (entry_path, folder / frame_name(i)):
            if linked.is_symlink():
                raise InputError(linked, "is a link: a clip bundle's files are read only inside it")
        entry = absolute_pan(read_frame_entry(entry_path), record, path)
        if entry.index != i:
            raise InputError(entry_path, f"holds frame {entry.index}, expected {i}")
        if before is not None and entry.seconds <= before.seconds:
            raise InputError(entry_path, f"its time {entry.seconds:g} s does not come after frame {i - 1}'s")
        if not 0.0 <= entry.seconds <= MAX_SECONDS:
            raise InputError(entry_path, f"its time {entry.seconds:g} s is not a clip's (0 to {MAX_SECONDS:g} s from the first frame)")
        if entry.state == "person" and not (folder / frame_name(i) / "scene.json").is_file():
            raise InputError(folder / frame_name(i), "missing: the frame's scene bundle")
        frames.append(entry)
        before = entry
    frames = tuple(frames)
    if not any(e.state == "person" for e in frames):
        raise InputError(path, "no frame of the clip shows a person to relight")
    return ClipBundle(path, record, frames)
