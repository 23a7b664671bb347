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


def read_record(path) -> dict:
    """``clip.json`` of the clip bundle at ``path``, checked."""
    record_path = Path(path) / RECORD
    record = read_json(record_path, "clip bundle record")
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise InputError(record_path, f"not a clip bundle record (format {FORMAT!r} expected)")
    if not isinstance(record.get("version"), int) or record["version"] > VERSION:
        raise InputError(record_path, f"version {record.get('version')!r} is not one this program reads (up to {VERSION})")
    if not isinstance(record.get("source"), dict):
        raise InputError(record_path, "has no source clip")
    return record


def read_frame_entry(path: Path) -> ClipFrameEntry:
    data = read_json(path, "clip frame record")
    try:
        pan = data.get("pan", [0.0, 0.0])
        pan_from = data.get("pan_from")
        entry = ClipFrameEntry(int(data["index"]), float(data["seconds"]), str(data["state"]), str(data.get("note", "")),
                               int(data.get("shot", 0)), (float(pan[0]), float(pan[1])), None if pan_from is None else int(pan_from))
    except (KeyError, TypeError, ValueError, IndexError):
        raise InputError(path, "is not a clip frame record (index, seconds, state)") from None
    if not all(np.isfinite(entry.pan)) or not np.isfinite(entry.seconds):
        raise InputError(path, "holds a time or pan that is not a finite number")
    if entry.state not in STATES:
        raise InputError(path, f"state must be one of {', '.join(STATES)}, got {entry.state!r}")
    return entry


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
    count = int(record.get("frames", 0))
    frames = tuple(absolute_pan(read_frame_entry(path / FRAMES / f"{frame_name(i)}.json"), record, path) for i in range(count))
    for i, entry in enumerate(frames):
        if entry.index != i:
            raise InputError(path / FRAMES / f"{frame_name(i)}.json", f"holds frame {entry.index}, expected {i}")
        if entry.state == "person" and not (path / FRAMES / frame_name(i) / "scene.json").is_file():
            raise InputError(path / FRAMES / frame_name(i), "missing: the frame's scene bundle")
    if not any(e.state == "person" for e in frames):
        raise InputError(path, "no frame of the clip shows a person to relight")
    return ClipBundle(path, record, frames)
