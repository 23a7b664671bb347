"""A clip's inference split into ranges of frames for several workers (``relight batch --ray``, or
worker processes), joined into one clip bundle without a seam.

What one frame hands the next (:mod:`viewer.photo.clip_inference`) is carried across a range's
start by overlap: each range begins ``OVERLAP`` frames before its first (inferred, or read when the
range before has finished them, never written), so its steadied maps have forgotten all but
0.6^8 = 1.7 % of where they began (:mod:`viewer.photo.steady`). What belongs to the shot is found
once for the whole clip before any range starts: the cuts (a pass over the frames' histograms,
:mod:`viewer.photo.shots`, a few milliseconds a frame), so every range numbers the shots alike; the
photo's lighting of a shot is fitted on its first frame with a person by whichever range needs it
(the same frame, the same fit). The camera's pan, which adds up over a shot, is counted by a range
begun within a shot from its own first frame; when every range is done, the pan each range had
reached at the frame before its first is set against the range before's, and the difference kept
in the record (``pan_offsets``), added to those frames' pans when the bundle is read.
"""

from __future__ import annotations

import bisect
import json
from dataclasses import dataclass
from pathlib import Path

from viewer.files.clip_reader import clip_frames
from viewer.files.imageio import write_text
from viewer.photo.clip_inference import finish_record, infer_frames, open_clip_bundle
from viewer.photo.photo_frame import MAX_SIZE, WORK_PERSON
from viewer.photo.shots import ShotCuts
from viewer.scene.clip_bundle import FRAMES, RECORD, frame_name, read_frame_entry, read_record

OVERLAP = 8  # frames a range begins before its first; a range has twice as many of its own at least


@dataclass(frozen=True)
class ClipRange:
    """Frames ``first`` to ``last`` (excluded) of a clip, begun ``warm`` frames before ``first``."""

    first: int
    last: int
    warm: int

    def to_json(self) -> list[int]:
        return [self.first, self.last, self.warm]


def split(frames: int, workers: int, temporal: str = "on", overlap: int = OVERLAP) -> list[ClipRange]:
    """``frames`` in at most ``workers`` ranges of nearly equal length, each of twice ``overlap`` frames
    at least (one range for a short clip), each after the first begun ``overlap`` frames early (frame
    by frame, ``temporal`` "off", nothing is carried: no overlap)."""
    count = max(1, min(workers, frames // max(2 * overlap, 1)))
    bounds = [round(k * frames / count) for k in range(count + 1)]
    warm = overlap if temporal == "on" else 0
    return [ClipRange(a, b, min(warm, a)) for a, b in zip(bounds, bounds[1:])]


def shot_starts(clip_path, start: float, end: float | None) -> tuple[list[int], int]:
    """(the frame each shot begins at, the frames from ``start`` to ``end``): every frame decoded once."""
    cuts = ShotCuts()
    starts, count = [0], 0
    for frame in clip_frames(clip_path, start, end):
        if cuts.shot_of(frame.rgb) == len(starts):
            starts.append(frame.index)
        count = frame.index + 1
    return starts, count


def open_ranges(clip_path, out_dir, workers: int, start: float = 0.0, end: float | None = None, size: int = WORK_PERSON,
                max_size: int = MAX_SIZE, temporal: str = "on", digest: str | None = None,
                overlap: int = OVERLAP) -> tuple[Path, list[ClipRange], dict | None]:
    """Make ``out_dir`` ready for the clip bundle of ``clip_path`` inferred in ranges (as
    :func:`viewer.photo.clip_inference.open_clip_bundle`, with the shots found and the ranges in its
    record): (the folder, the ranges, the earlier record when the bundle there is whole already)."""
    out_dir, record, earlier = open_clip_bundle(clip_path, out_dir, start, end, size, max_size, temporal, digest)
    if earlier is not None:
        return out_dir, [], earlier
    starts, count = shot_starts(clip_path, start, end) if temporal == "on" else ([0], None)
    if count is None:
        count = sum(1 for _ in clip_frames(clip_path, start, end))
    ranges = split(count, workers, temporal, overlap)
    record.update(expected_frames=count, shot_starts=starts, ranges=[r.to_json() for r in ranges])
    write_text(out_dir / RECORD, json.dumps(record, indent=1) + "\n")
    return out_dir, ranges, None


def infer_range(clip_path, out_dir, clip_range: ClipRange, device: str = "cpu", networks=None, ctx=None, progress=None) -> dict:
    """One range of a clip bundle made ready by :func:`open_ranges` (a worker's task): what
    :func:`viewer.photo.clip_inference.infer_frames` did."""
    record = read_record(out_dir)
    return infer_frames(clip_path, out_dir, record, clip_range.first, clip_range.last, clip_range.warm,
                        record.get("shot_starts") if record["temporal"] == "on" else None, device=device, networks=networks,
                        progress=progress, ctx=ctx)


def finish_ranges(clip_path, out_dir, ranges: list[ClipRange], results: list[dict]) -> dict:
    """Every range done (``results`` in the order of ``ranges``): the pans joined across the ranges'
    starts, the record made complete. Returns it."""
    out_dir = Path(out_dir)
    record = read_record(out_dir)
    starts = record.get("shot_starts") or [0]
    offsets: dict[str, list[float]] = {}
    for clip_range, result in zip(ranges, results):
        begin = clip_range.first - clip_range.warm
        shot = bisect.bisect_right(starts, begin) - 1
        if record["temporal"] != "on" or begin <= starts[shot] or result["warm_pan"] is None:
            continue  # the range's pans count from their shots' first frames already
        before = read_frame_entry(out_dir / FRAMES / f"{frame_name(clip_range.first - 1)}.json")
        reached = [before.pan[i] + (offsets[str(before.pan_from)][i] if before.pan_from is not None else 0.0) for i in (0, 1)]
        offsets[str(begin)] = [round(reached[i] - result["warm_pan"][i], 4) for i in (0, 1)]
    return finish_record(clip_path, out_dir, record, results, pan_offsets=offsets)
