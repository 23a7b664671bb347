"""Relight the two real photos of ``../shared/data/photos`` under three of the shared CC0 maps with the
shipped networks, for docs/: ``docs/photos_relit.png`` (one row per photo: the photo, the inferred
albedo and normals, then the relit image under each map with refined shadows) and the inference
timings as JSON.

The hand-made masks (CC BY-NC-SA 4.0) are used here for evaluation only; nothing of them is shipped
(the sheet shows the photos relit, which is what the project is for).

    .venv/bin/python tools/relight_real_photos.py [--out docs] [--size 512]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from viewer.envmap import load_envmap
from viewer.gl import Engine, EngineOptions, create_headless_context
from viewer.imageio import linear_to_srgb
from viewer.inference import infer, load_networks
from viewer.lightfit import lights_for_map
from viewer.refinement import Refiner
from viewer.render import RenderSettings, apply_settings, render_frame
from viewer.scene import load_scene

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
PHOTOS = ("unsplash-1507274733827", "unsplash-1535323700481")
MAPS = (("venice_sunset_1k", 200.0), ("studio_small_03_1k", 30.0), ("immenstadter_horn_1k", 180.0))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs")
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--work", default="out/real_photos", help="where the scene bundles go")
    args = parser.parse_args()
    out, work = Path(args.out), Path(args.work)
    nets = load_networks("cpu")
    refiner = Refiner()
    ctx = create_headless_context()
    maps = []
    for name, yaw in MAPS:
        env = load_envmap(SHARED / "hdri" / f"{name}.hdr").downsampled(256)
        maps.append((name, yaw, env, lights_for_map(env, 16)[0]))
    rows, record = [], {}
    for stem in PHOTOS:
        mask = SHARED / "photos" / f"{stem}.mask.png"
        t0 = time.perf_counter()
        rec = infer(SHARED / "photos" / f"{stem}.jpg", mask, work / stem, size=args.size, networks=nets)
        record[stem] = {"inference": rec["seconds"], "inference_total": rec["seconds_total"], "relight_seconds": {}}
        scene = load_scene(work / stem)
        m = scene.mask[..., None]
        row = [linear_to_srgb(scene.photo), np.where(m, linear_to_srgb(scene.albedo), 1.0), np.where(m, scene.normal * 0.5 + 0.5, 1.0)]
        eng = Engine(ctx, scene, EngineOptions())
        try:
            for name, yaw, env, lights in maps:
                t0 = time.perf_counter()
                eng.set_environment(env.pixels)
                settings = RenderSettings(yaw=yaw, visibility="refined")
                apply_settings(eng, scene, lights, settings, True)
                render_frame(eng, settings, refiner)
                record[stem]["relight_seconds"][name] = round(time.perf_counter() - t0, 3)
                row.append(eng.read_display().astype(np.float32) / 255.0)
        finally:
            eng.release()
        rows.append(np.concatenate(row, axis=1))
        print(f"{stem}: inferred in {rec['seconds_total']:.2f} s, relit under {len(maps)} maps")
    _sheet(rows, [m[0] for m in maps], out / "photos_relit.png")
    (out / "photos_relit.json").write_text(json.dumps({"size": args.size, "maps": [m[:2] for m in MAPS], **record}, indent=1) + "\n")
    print(f"wrote {out / 'photos_relit.png'} and {out / 'photos_relit.json'}")
    return 0


def _sheet(rows, map_names, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    titles = ["photo (framed)", "albedo (inferred)", "normal (inferred)"] + [f"relit: {n}" for n in map_names]
    n = len(titles)
    fig, axes = plt.subplots(len(rows), 1, figsize=(2.2 * n, 2.4 * len(rows)), dpi=110, squeeze=False)
    for ax, row in zip(axes[:, 0], rows):
        ax.imshow(np.clip(row, 0, 1))
        ax.set_xticks([(k + 0.5) * row.shape[0] for k in range(n)])
        ax.set_xticklabels(titles, fontsize=8)
        ax.xaxis.tick_top()
        ax.set_yticks([])
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
