"""One clip spread over a pool's workers (``relight render CLIP --ray``): Ray actors, each one process
with its own GL context and networks. (A batch spreads a clip's relit parts with :func:`part_tasks` too,
:mod:`viewer.batch.run`.)

- **The inference in ranges of frames** (:mod:`viewer.photo.clip_ranges`): the shots found and the
  person chosen once by this driver, each range begun ``OVERLAP`` frames early so that what one frame
  hands the next (the steadied maps, the person followed) has forgotten where it began; the pans
  joined when the last range is in.
- **The relit parts** (:func:`viewer.output.clip_render.render_clip`'s ``share``): the parts not made
  yet handed out a few at a time (an actor that finishes early takes the next), each written whole
  into the parts folder this driver made ready; the driver then joins them with the source's audio.
  Every frame is a function of its index alone, so the joins show no seam.

Both resume as a single process does: a range's finished frames and a finished part are kept by the
next run. A range or part that fails stops the clip with its one line (Ray runs a task whose actor
died again, :mod:`viewer.batch.pools`).
"""

from __future__ import annotations

import itertools
from pathlib import Path

from viewer.errors import InputError

POLL_SECONDS = 0.5  # how often the progress is counted (the frames and parts written so far)
PARTS_A_TASK = 2  # parts handed to an actor at a time: a few, so that the last actor to finish is not long alone


def run_tasks(pool, tasks: list[dict], poll=None) -> list[dict]:
    """Every task of ``tasks`` run on ``pool``; their results in the same order. ``poll()`` is called
    while they run; a task that failed is the clip's one line, after the others have finished (what
    they wrote is kept for the next run)."""
    ids = itertools.count()
    order = {}
    for task in tasks:
        order[task_id := next(ids)] = len(order)
        pool.submit({**task, "id": task_id})
    results: list[dict | None] = [None] * len(tasks)
    while any(r is None for r in results):
        for r in pool.results(timeout=POLL_SECONDS):
            if r.get("id") in order:
                results[order[r["id"]]] = r
        if poll is not None:
            poll()
    failed = next((r for r in results if not r["ok"]), None)
    if failed is not None:
        raise InputError(None, failed["error"])
    return results


def infer_spread(pool, clip, target: Path, request, digest: str, device: str = "cpu", progress=None, cached: bool = False) -> dict:
    """The clip bundle of ``clip`` made in ``target`` by ``pool``'s workers, a range each (one range
    for a short clip); its record (as :func:`viewer.photo.clip_inference.infer_clip` returns it).
    ``progress(done, total, None)`` as frames are finished."""
    from viewer.photo.clip_ranges import open_ranges
    from viewer.scene.clip_bundle import FRAMES

    bundle = open_ranges(clip, target, pool.size, request, digest, cached=cached)
    try:
        if bundle.earlier is not None:
            return {**bundle.earlier, "frames_kept_from_earlier_run": bundle.earlier["frames"]}
        total = bundle.ranges[-1].last

        def poll():
            if progress is not None:
                progress(min(sum(1 for _ in (bundle.path / FRAMES).glob("*.json")), total), total, None)

        tasks = [{"kind": "infer_range", "photo": str(Path(clip).resolve()), "bundle": str(bundle.path.resolve()),
                  "range": r.to_json(), "key": bundle.key, "device": device} for r in bundle.ranges]
        results = run_tasks(pool, tasks, poll)
        return bundle.finish(clip, [r["range_result"] for r in results])
    finally:
        bundle.close()


def parts_sharer(pool, task: dict, folder: Path, progress=None):
    """``render_clip``'s ``share``: the parts given made by ``pool``'s workers, ``PARTS_A_TASK`` a task
    (``task``: what every part's task holds, :meth:`viewer.batch.worker.Worker.render_parts`);
    ``progress(done, total)`` in frames as parts are written into ``folder``."""

    def share(parts) -> None:
        total = sum(p.last - p.first for p in parts)

        def poll():
            if progress is not None:
                progress(sum(p.last - p.first for p in parts if (folder / p.name).is_file()), total)

        run_tasks(pool, part_tasks(task, [p.index for p in parts]), poll)

    return share


def part_tasks(task: dict, parts: list[int]) -> list[dict]:
    """The workers' tasks for the relit ``parts`` (their numbers), ``PARTS_A_TASK`` a task."""
    return [{**task, "kind": "render_parts", "parts": parts[k:k + PARTS_A_TASK]} for k in range(0, len(parts), PARTS_A_TASK)]


def open_pool(address: str, workers: int | None):
    """A pool of Ray actors, one thread each (the cluster's CPUs, or ``workers``), on the cluster at
    ``address`` (``auto``, ``local``: one started for this run, or ``HOST:PORT``)."""
    from viewer.batch.pools import RayPool

    if workers is not None and workers < 1:
        raise InputError(None, f"--workers: 1 or more, got {workers}")
    return RayPool(address, workers, 1)
