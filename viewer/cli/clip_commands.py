"""``relight infer CLIP`` and ``relight render`` of a clip: a video in, a relit video out.

``relight render`` takes a clip bundle, or a clip itself (its bundle inferred into the cache once,
as a photo's is, and finished there if a run stopped). The output keeps the source's frames,
timing, framing (its size, or uniformly scaled by ``--max-size``) and audio; the map turns only if
``--turn`` says so."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from viewer.cli.output_paths import INFERRED_ONLY, inferred_only, writable
from viewer.errors import InputError
from viewer.files.clip_reader import check_range, is_clip
from viewer.files.ownership import file_sha256


def progress_bar(total: int, what: str, position: int | None = None):
    from tqdm import tqdm

    return tqdm(total=total, unit="frame", desc=what, leave=False, dynamic_ncols=True, position=position)


def bundle_options(clip, args, out=None) -> tuple[Path, dict]:
    """(where the clip bundle of ``clip`` goes: ``out``, or the cache's when None; the options it is
    inferred with, :func:`viewer.photo.clip_inference.infer_clip`'s: its request, ...) from ``args`` (--start, --end,
    --size, --max-size, --device, --temporal, --person, --people)."""
    from viewer.files.clip_reader import probe_clip
    from viewer.lighting.lightfit.cache import bundles_dir
    from viewer.nets.device import DEFAULT_DEVICE
    from viewer.photo.clip_cache import ClipRequest, cached_clip_path
    from viewer.photo.clip_inference import check_frame_size
    from viewer.photo.frames import MAX_SIZE, WORK_PERSON

    size = WORK_PERSON if out is None else (getattr(args, "size", None) or WORK_PERSON)  # render's --size is the maps' at render
    max_size = getattr(args, "max_size", None) or MAX_SIZE
    temporal = args.temporal or "on"
    person, people = getattr(args, "person", None), getattr(args, "people", None) or "one"
    check_frame_size(clip, probe_clip(clip), max_size)  # (a clip that cannot be read, or is too small: one line before any bar)
    digest = file_sha256(clip)  # read once: the cache's path and the bundle's key
    request = ClipRequest(args.start, args.end, size, max_size, temporal, person, people)
    target = Path(out) if out is not None else cached_clip_path(clip, bundles_dir(), request, digest)
    return target, {"request": request, "digest": digest, "device": getattr(args, "device", DEFAULT_DEVICE), "cached": out is None}


def say_bundle(clip, target: Path, record: dict, seconds: float, pool=None) -> None:
    """What a clip's inference did, said: whom it relit, where no one is, the bundle's frames and speed."""
    from viewer.photo.clip_person import person_said

    kept, states = record["frames_kept_from_earlier_run"], record["states"]
    rate = f", {60 * (record['frames'] - kept) / max(seconds, 1e-9):.1f} frames a minute" if record["frames"] > kept else ""
    shots = f", {record['shots']} shot{'s' if record['shots'] != 1 else ''}" if record.get("shots") else ", frame by frame"
    if pool is not None and record["frames"] > kept:
        count = len(record["ranges"])  # (open_ranges writes them for every bundle it leaves to the workers)
        shots += f"; in {count} range{'s' if count != 1 else ''} over {pool.size} workers"
    print(person_said(clip, record, target))
    for gap in record.get("gaps", []):
        print(gap)
    print(f"clip bundle of {clip}: {target} ({record['frames']} frames: {states['person']} with the person, "
          f"{states['no person']} without, {states['lost']} lost{shots}; {kept} kept from an earlier run; {seconds:.1f} s{rate})")


def clip_bundle(clip, args, out=None, window=None, pool=None, planned: tuple | None = None) -> Path:
    """The clip bundle of ``clip`` (:func:`bundle_options`, or ``planned``: what it gave already): written
    into ``out``, or the cache's when None; a progress bar with frames, their rate and the time left (and
    in ``window``, a window already open, whose context the inference then uses; or by ``pool``'s
    workers, a range of frames each: :mod:`viewer.batch.spread_clip`)."""
    from viewer.photo.clip_inference import infer_clip

    target, options = planned or bundle_options(clip, args, out)
    t0 = time.perf_counter()
    with progress_bar(0, f"inferring {Path(clip).name}") as bar:
        def progress(done, total, entry):
            bar.total = total
            bar.update(done - bar.n)
            if window is not None:
                left = bar.format_dict
                rate = left.get("rate")
                words = f", about {(total - done) / rate:.0f} s left" if rate else ""
                window.show_message(f"Preparing {Path(clip).name}", done / max(total, 1), f"frame {done} of {total}{words}")

        if window is not None:
            window.show_message(f"Preparing {Path(clip).name}", 0.0, "reading the clip, finding the person...")
        if pool is not None:
            from viewer.batch.spread_clip import infer_spread

            record = infer_spread(pool, clip, target, progress=progress, **options)
        else:
            record = infer_clip(clip, target, progress=progress, ctx=window.ctx if window is not None else None, **options)
    say_bundle(clip, target, record, time.perf_counter() - t0, pool)
    return target


@dataclass
class ViewedClip:
    window: object  # viewer.app.window.Window, open
    bundle: object  # viewer.scene.clip_bundle.ClipBundle
    first: Path  # the scene bundle of the first frame shown (a person's)


def view_clip_bundle(args) -> ViewedClip:
    """``relight view CLIP`` (or a clip bundle): the window opened first (its context serves the
    inference, shown in it, when the clip's bundle is not in the cache yet), then the bundle read."""
    from viewer.app.window import Window
    from viewer.output.clip_frames import ClipFrames
    from viewer.scene.clip_bundle import load_clip_bundle

    if is_clip(args.scene):
        check_range(args.scene, args.start, args.end)
    elif inferred_only(args):
        raise InputError(args.scene, f"{INFERRED_ONLY} choose how a clip is inferred: give the clip itself, "
                                     "or infer its bundle with them")
    window = Window(960, 720, f"relight - {Path(args.scene).name}")
    try:
        bundle = load_clip_bundle(clip_bundle(args.scene, args, window=window) if is_clip(args.scene) else args.scene)
        return ViewedClip(window, bundle, bundle.scene_path(ClipFrames(bundle).shown(0)[1]))
    except BaseException:
        window.release()
        raise


def cmd_infer_clip(args) -> int:
    from viewer.photo.clip_cache import clip_target

    if args.mask is not None:
        raise InputError(args.mask, "a mask is for a photo: a clip's person is found in every frame")
    target = clip_target(args.output)
    writable(target.parent, folder=True)
    if target == Path(args.photo).resolve() or target in Path(args.photo).resolve().parents:
        raise InputError(args.output, "is the clip or holds it: give another folder")
    clip_bundle(args.photo, args, target)
    return 0


