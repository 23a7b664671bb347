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
begun within a shot from the first frame it infers (``OVERLAP`` before its own); when every range is done, the pan each range had
reached at the frame before its first is set against the range before's, and the difference kept
in the record (``pan_offsets``), added to those frames' pans when the bundle is read.
"""

from __future__ import annotations

import contextlib
import json
from dataclasses import dataclass
from pathlib import Path

from viewer.errors import InputError
from viewer.files.clip_reader import clip_frames
from viewer.files.imageio import write_text
from viewer.photo.clip_cache import ClipRequest, source_state, unchanged
from viewer.photo.clip_inference import ClipRange, finish_ranges, infer_frames, locked_bundle, open_clip_bundle
from viewer.photo.shots import ShotCuts
from viewer.scene.clip_bundle import RECORD, read_record

OVERLAP = 8  # frames a range begins before its first; a range has twice as many of its own at least


def split(frames: int, workers: int, temporal: str = "on", overlap: int = OVERLAP) -> list[ClipRange]:
    """``frames`` in at most ``workers`` ranges, twice ``overlap`` frames a range at least on average (one
    range for a short clip), each after the first begun ``overlap`` frames early (one at least: the pan is joined
    on the frame before a range's first; frame by frame, ``temporal`` "off", nothing is carried: no
    overlap). The ranges take equal work, the frames begun early counted: the first is ``overlap``
    frames longer than the others (equal ranges left the first worker idle while the others inferred
    their overlap: 8 frames of 65 on a crowd clip on two workers)."""
    count = max(1, min(workers, frames // max(2 * overlap, 1)))
    warm = max(overlap, 1) if temporal == "on" else 0
    work = (frames + (count - 1) * warm) / count  # each range's frames, its own and those begun early
    bounds = [0] + [round(work + k * (work - warm)) for k in range(count - 1)] + [frames]
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


@dataclass
class RangedBundle:
    """A clip bundle made ready for ranges (:func:`open_ranges`): its folder, its ranges (none when the
    bundle was whole already: ``earlier`` is its record), and the lock on it, held until :meth:`close`
    (one run at a time makes a clip bundle; the workers inferring its ranges do not take it)."""

    path: Path
    ranges: list[ClipRange]
    earlier: dict | None
    lock: contextlib.ExitStack
    key: str  # the bundle's (what its clip, options and the inference hash to)
    source: tuple  # the clip's file as it was when the bundle was made ready (clip_cache.source_state)

    def finish(self, clip_path, results: list[dict]) -> dict:
        """Every range done (``results`` in the order of the ranges): the record made complete
        (:func:`viewer.photo.clip_inference.finish_ranges`), and the bundle not kept, one line, when the clip changed
        while its ranges were inferred (:func:`viewer.photo.clip_cache.unchanged`)."""
        record = finish_ranges(clip_path, self.path, self.ranges, results)
        unchanged(clip_path, self.source, self.path)
        return record

    def close(self) -> None:
        self.lock.close()


def open_ranges(clip_path, out_dir, workers: int, request: ClipRequest = ClipRequest(), digest: str | None = None,
                overlap: int = OVERLAP, cached: bool = False) -> RangedBundle:
    """Make ``out_dir`` ready for the clip bundle of ``clip_path`` inferred in ranges (as
    :func:`viewer.photo.clip_inference.open_clip_bundle`, with the shots found, the person chosen and
    the ranges in its record; an unfinished bundle of the same clip and options keeps the ranges it
    was begun in). ``cached``: ``out_dir`` is the cache's (:func:`viewer.photo.clip_inference.locked_bundle`)."""
    start, end = request.start, request.end
    out_dir, lock = locked_bundle(clip_path, out_dir, start, end, cached)
    held = contextlib.ExitStack()
    held.enter_context(lock)
    try:
        source = source_state(clip_path)
        out_dir, record, earlier = open_clip_bundle(clip_path, out_dir, request, digest)
        if earlier is not None:
            return RangedBundle(out_dir, [], earlier, held, record["key"], source)
        if not record.get("ranges") or not record.get("shot_starts"):
            starts, count = shot_starts(clip_path, start, end)  # (the frames counted: each range's end known)
            ranges = split(count, workers, request.temporal, overlap)
            record.update(expected_frames=count, shot_starts=starts, ranges=[r.to_json() for r in ranges])
            write_text(out_dir / RECORD, json.dumps(record, indent=1) + "\n")
        return RangedBundle(out_dir, [ClipRange(*r) for r in record["ranges"]], None, held, record["key"], source)
    except BaseException:
        held.close()
        raise


def infer_range(clip_path, out_dir, clip_range: ClipRange, key: str | None = None, device: str = "cpu", networks=None, ctx=None,
                progress=None) -> dict:
    """One range of a clip bundle made ready by :func:`open_ranges` (a worker's task; ``key``: the
    bundle's, as the driver made it ready): what :func:`viewer.photo.clip_inference.infer_frames` did.
    A bundle not made ready for ranges, or made again since (another key), is one line."""
    record = read_record(out_dir)
    if (key is not None and record.get("key") != key) or clip_range.to_json() not in record.get("ranges", []) or \
            (record["temporal"] == "on" and not record.get("shot_starts")):
        raise InputError(Path(out_dir) / RECORD, f"is not ready for frames {clip_range.first} to {clip_range.last - 1} "
                                                 "(made again by another run?): run the batch again")
    return infer_frames(clip_path, out_dir, record, clip_range, record.get("shot_starts") if record["temporal"] == "on" else None,
                        device=device, networks=networks, progress=progress, ctx=ctx)
