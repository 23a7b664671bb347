"""``relight bench matte``: the person's matte against the hand-made masks, each step and each
matting solver measured (quality and time).

For each photo of ``--photos`` with a hand-made mask beside it (``<stem>.mask.png``, evaluation
only), at the output frame (the photo capped at 2048 px), and for the same person composited on a
plain pink backdrop by that mask (:func:`viewer.lab.bench.metrics.on_backdrop`):

- the pose model's segmentation alone (thresholded at 0.5);
- the band decided by colour, the background's holes and the plain backdrop the person encloses
  (:func:`viewer.photo.matting.decided_outline`), with no soft edge;
- the soft edge solved by each of pymatting's alpha solvers (closed-form, KNN, large-kernel,
  random-walk, learning-based) at several band widths, with the foreground colours;

each with spill and cut against the hand-made mask, bleed of the foreground colours, kept (on the
backdrop), and its seconds (medians of ``--repeats``). Writes ``matte.json``.
"""

from __future__ import annotations

import json
import time
from functools import partial
from pathlib import Path

import numpy as np

from viewer.files.imageio import srgb_to_linear, write_text
from viewer.lab.bench.metrics import bleed, kept_backdrop, on_backdrop, spill_cut
from viewer.photo import matting
from viewer.photo.frames import output_frame, read_mask, read_photo
from viewer.photo.pose_masks import person_height
from viewer.resize import resize

SOLVERS = ("cf", "knn", "lkm", "rw", "lbdm")
EDGES = (0.0016, 0.003, 0.004, 0.006)  # half-widths of the soft edge's band, of the person's height


def _solver(name: str):
    import pymatting

    return {"cf": pymatting.estimate_alpha_cf, "knn": pymatting.estimate_alpha_knn, "lkm": pymatting.estimate_alpha_lkm,
            "rw": pymatting.estimate_alpha_rw, "lbdm": pymatting.estimate_alpha_lbdm}[name]


def _timed(fn, repeats: int):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, float(np.median(times))


def _scores(alpha, foreground, linear, hand, photo, backdrop: bool) -> dict:
    out = spill_cut(alpha, hand)
    out["bleed"] = bleed(foreground, alpha, linear)
    if backdrop:
        out["kept"] = kept_backdrop(alpha, photo, hand)
    return out


def measure(photo: np.ndarray, hand: np.ndarray, backdrop: bool, solvers, edges, repeats: int) -> dict:
    """Every step and solver on one photo (uint8 sRGB at the frame) against its hand-made mask."""
    from viewer.photo.segmentation import find_person

    linear = srgb_to_linear(photo.astype(np.float32) / 255.0)
    person, t_find = _timed(lambda: find_person(photo), 1)
    h, w = photo.shape[:2]
    height = person_height(person.segmentation > 0.5)
    row: dict = {"frame": [w, h], "person_height": height, "find_person_seconds": round(t_find, 3)}
    seg = (person.segmentation > 0.5).astype(np.float32)
    row["segmentation"] = _scores(seg, linear, linear, hand, photo, backdrop)
    (decided, holes, gaps, half), t_band = _timed(lambda: matting.decided_outline(photo, person), repeats)
    row["band"] = {**_scores((decided & ~holes & ~gaps).astype(np.float32), linear, linear, hand, photo, backdrop),
                   "seconds": t_band}
    row["edges"] = []
    for solver in solvers:
        for edge in edges:
            half = max(matting.MIN_EDGE, edge * height)
            solve = partial(matting.edge_alpha, photo, decided, half, holes, _solver(solver), gaps)
            alpha, t_edge = _timed(solve, repeats)
            fg, t_fg = _timed(lambda alpha=alpha, half=half: srgb_to_linear(
                matting.foreground_colours(photo.astype(np.float32) / 255.0, alpha, half)), repeats)
            row["edges"].append({"solver": solver, "edge": edge, "half_width_px": round(half, 2),
                                 **_scores(alpha, fg, linear, hand, photo, backdrop),
                                 "seconds": {"edge": t_edge, "foreground": t_fg}})
    return row


def run_matte_benchmark(photos, output="out/bench_matte.json", solvers=SOLVERS, edges=EDGES, repeats: int = 3,
                        progress=None) -> dict:
    photos = Path(photos)
    paths = sorted(p for p in photos.glob("*.jpg") if p.with_name(p.stem + ".mask.png").is_file())
    if not paths:
        from viewer.errors import InputError

        raise InputError(photos, "no .jpg photos with a hand-made <stem>.mask.png beside them")
    result: dict = {"defaults": {"solver": "cf", "edge": matting.EDGE, "solve_height": matting.SOLVE_HEIGHT},
                    "photos": []}
    start = time.perf_counter()
    for path in paths:
        notes: list = []
        photo = read_photo(path, notes)
        h, w = photo.shape[:2]
        frame = output_frame((w, h))
        hand = np.clip(resize(read_mask(path.with_name(path.stem + ".mask.png"), (h, w), notes), frame), 0, 1)
        photo = resize(photo, frame)
        for backdrop in (False, True):
            image = on_backdrop(photo, hand) if backdrop else photo
            row = measure(image, hand, backdrop, solvers, edges, repeats)
            row["photo"] = path.name + (" on a pink backdrop" if backdrop else "")
            result["photos"].append(row)
            if progress is not None:
                progress(row["photo"])
    result["seconds"] = round(time.perf_counter() - start, 1)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    write_text(output, json.dumps(result, indent=1) + "\n")
    return result


def table(result: dict) -> str:
    """The figures as text: one block per photo, a line per step or solver and band width."""
    lines = []
    for row in result["photos"]:
        lines.append(f"{row['photo']} ({row['frame'][0]}x{row['frame'][1]}, person {row['person_height']} px)")
        head = f"  {'step':28s} {'spill':>6s} {'cut':>6s} {'bleed':>6s} {'kept':>6s} {'seconds':>8s}"
        lines.append(head)

        def line(name, s, seconds):
            kept = f"{s['kept']:6.3f}" if "kept" in s else f"{'':6s}"
            lines.append(f"  {name:28s} {s['spill']:6.3f} {s['cut']:6.3f} {s['bleed']:6.3f} {kept} {seconds:8.3f}")

        line("segmentation", row["segmentation"], row["find_person_seconds"])
        line("band decided by colour", row["band"], row["band"]["seconds"])
        for e in row["edges"]:
            line(f"+ {e['solver']} edge {e['half_width_px']:.1f} px", e, e["seconds"]["edge"] + e["seconds"]["foreground"])
    return "\n".join(lines)
