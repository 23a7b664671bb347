"""``relight bench matte --backdrops``: people with hand-made masks composited on plain backdrops,
through ``relight infer``'s automatic matte and relit: is the backdrop the person encloses (between
an arm and the body, hair and the neck, the legs) taken out, and is the person kept?

Every photo of the folders given with a hand-made mask beside it (``<stem>.mask.png``, evaluation
only) is brought to its output frame and composited by that mask on each of ``BACKDROPS``, flat
(:func:`viewer.lab.bench.metrics.on_backdrop`) and as a studio (:func:`viewer.lab.bench.metrics.on_studio`:
a gentle gradient, a floor, the person's cast shadow, a contact shadow, noise); the composite is
inferred as ``relight infer`` infers a photo and relit with a transparent background under the
neutral map as ``relight bench photos --set`` relights it. Per composite, against the mask:

- *kept*: :func:`viewer.lab.bench.metrics.kept_backdrop` (the person's own clothes of the backdrop's
  colour count too) and *kept outside*: the same outside the mask only (the backdrop kept);
- *spill* and *cut* (:func:`viewer.lab.bench.metrics.spill_cut`);
- *gaps found* and *gaps kept*: the background the mask's person encloses
  (:func:`viewer.lab.bench.metrics.gaps_found`);
- *bleed* of the relit person (:func:`viewer.lab.bench.metrics.bleed`, as the set measures it);
- the matte's seconds inside the inference (band, edge, foreground colours).

Writes ``backdrops.json`` (``--before``: an earlier run's, kept beside this one's figures).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import srgb_to_linear, write_text
from viewer.gl import Engine, EngineOptions, create_headless_context
from viewer.lab.bench.metrics import bleed, gaps_found, kept_backdrop, on_backdrop, on_studio, spill_cut
from viewer.lab.bench.photo_set import collect, lights_loader, relit_person
from viewer.photo.frames import output_frame, read_mask, read_photo
from viewer.photo.inference import ClipFrame, infer_scene, load_networks
from viewer.resize import resize

BACKDROPS = {"pink": (236, 150, 190), "navy": (30, 40, 80), "white": (242, 242, 240), "grey": (128, 128, 128)}


def media(dirs) -> list[tuple[Path, Path]]:
    """(photo, its hand-made mask) of every photo of ``dirs`` with a ``<stem>.mask.png`` beside it."""
    pairs = [(p, p.with_name(p.stem + ".mask.png")) for p in collect(dirs)]
    return [(photo, mask) for photo, mask in pairs if mask.is_file()]


def _round(v):
    return None if v is None else round(float(v), 4)


def measure_composite(image: np.ndarray, hand: np.ndarray, name: str, ctx, nets, light_cache, maps_dir: Path) -> dict:
    """One composite's row (see the module's docstring): ``image`` uint8 sRGB at its output frame,
    ``hand`` the mask there."""
    t = time.perf_counter()
    result = infer_scene(name, networks=nets, ctx=ctx, clip=ClipFrame(image))
    infer_s = time.perf_counter() - t
    scene = result["scene"]
    eng = Engine(ctx, scene, EngineOptions())
    try:
        person, alpha = relit_person(eng, scene, light_cache, maps_dir)
    finally:
        eng.release()
    matte = result["record"]["matte"]
    return {"kept": _round(kept_backdrop(alpha, image, hand)),
            "kept_outside": _round(kept_backdrop(alpha, image, hand, hand < 0.5)),
            **{k: _round(v) for k, v in spill_cut(alpha, hand).items()},
            **{f"gaps_{k}": _round(v) for k, v in gaps_found(alpha, hand).items()},
            "bleed": _round(bleed(person, alpha, srgb_to_linear(image.astype(np.float32) / 255.0))),
            "matte_seconds": matte["seconds"], "gaps_px": matte.get("gaps_px"), "infer_s": round(infer_s, 2)}


def run_backdrops_benchmark(dirs, maps_dir, output="out/bench_backdrops.json", before=None, progress=print) -> dict:
    """Measure every composite of the photos with hand-made masks in ``dirs``; write ``output``."""
    pairs = media(dirs)
    if not pairs:
        from viewer.errors import InputError

        raise InputError(dirs[0] if dirs else None, "no photos with a hand-made <stem>.mask.png beside them")
    ctx = create_headless_context()
    nets = load_networks()
    light_cache = lights_loader()
    rows = []
    start = time.perf_counter()
    for path, mask in pairs:
        photo = read_photo(path, [])
        h, w = photo.shape[:2]
        frame = output_frame((w, h))
        hand = np.clip(resize(read_mask(mask, (h, w), []), frame), 0, 1)
        photo = resize(photo, frame)
        for colour, rgb in BACKDROPS.items():
            for kind, composite in (("flat", on_backdrop), ("studio", on_studio)):
                figures = measure_composite(composite(photo, hand, rgb), hand, f"{path.stem} on {kind} {colour}", ctx,
                                            nets, light_cache, Path(maps_dir))
                row = {"photo": path.name, "backdrop": colour, "kind": kind, **figures}
                rows.append(row)
                progress(f"  {path.name} on {kind} {colour}: kept outside {row['kept_outside']}, spill {row['spill']}, "
                         f"cut {row['cut']}, gaps found {row['gaps_found']}, bleed {row['bleed']}")
    result = {"composites": rows, "seconds": round(time.perf_counter() - start, 1),
              "command": "relight bench matte --backdrops --set " + " ".join(str(d) for d in dirs)}
    if before:
        result["before"] = json.loads(Path(before).read_text())
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    write_text(output, json.dumps(result, indent=1) + "\n")
    return result


COLUMNS = ("kept", "kept_outside", "spill", "cut", "gaps_found", "gaps_kept", "bleed")


def backdrops_table(result: dict) -> str:
    """The figures as a Markdown table, "before -> now" where an earlier run is given."""
    before = {(r["photo"], r["backdrop"], r["kind"]): r for r in result.get("before", {}).get("composites", [])}

    def cell(row, key):
        v = None if row is None else row.get(key)
        return "-" if v is None else f"{v:.3f}"

    lines = ["| photo | backdrop | " + " | ".join(c.replace("_", " ") for c in COLUMNS) + " | matte s |",
             "|---|---|" + "---|" * (len(COLUMNS) + 1)]
    for row in result["composites"]:
        old = before.get((row["photo"], row["backdrop"], row["kind"]))
        cells = [(cell(old, c) + " -> " if old else "") + cell(row, c) for c in COLUMNS]
        seconds = [f"{sum(r['matte_seconds'].values()):.2f}" for r in (old, row) if r]
        lines.append(f"| {row['photo'][:32]} | {row['kind']} {row['backdrop']} | " + " | ".join(cells)
                     + f" | {' -> '.join(seconds)} |")
    return "\n".join(lines)
