"""``relight bench bodyfit``: how good a body fitted to a photo is as a depth prior, against the
prior the lab's experiment assumed (:mod:`viewer.lab.data.body_prior`) and a flat figure.

For the first ``limit`` people of a dataset, one lighting each: the photo (the relit person over the map, exposed
and encoded as the networks see it) goes to MediaPipe, anny is fitted to its landmarks
(:mod:`viewer.lab.data.body_fit`), and the fitted body is rasterized in the camera. Per person:
the mask IoU against the person's, and the median-aligned depth L1 over the pixels both cover,
for the fitted body, the experiment's prior and a flat figure at the person's median depth, with
the fit's reprojection error in pixels and its time.
"""

from __future__ import annotations

import json
import time

import numpy as np

from viewer.files.imageio import write_text
from viewer.scene.camera import Camera


def _scores(depth: np.ndarray, mask: np.ndarray, truth) -> dict:
    both = truth.mask & mask
    diff = (depth - truth.depth)[both]
    diff = diff - np.median(diff) if diff.size else diff
    return {"iou": float(both.sum() / max((truth.mask | mask).sum(), 1)),
            "depth_l1_cm": float(np.abs(diff).mean() * 100) if diff.size else None}


def run_body_fit_benchmark(data, limit: int = 12, output="out/bench_bodyfit.json", progress=None) -> dict:
    from viewer.lab.data.body_fit import fit_body, landmarks
    from viewer.lab.data.body_prior import body_prior
    from viewer.lab.data.geometry import vertex_normals
    from viewer.lab.data.humans import rasterize
    from viewer.lab.data.loader import RelightDataset
    from viewer.nets.photo import exposure_scale
    from viewer.scene.bundle import load_scene
    from viewer.twin.srgb import srgb_encode

    ds = RelightDataset(data, fields=("image", "background", "mask"))
    people = []
    seen = set()
    for i, (sample, _) in enumerate(ds.items):  # one lighting per person
        if sample not in seen:
            seen.add(sample)
            people.append(i)
    people = people[:limit]
    rows = []
    for n, i in enumerate(people):
        sample, _ = ds.items[i]
        item = ds[i]
        photo = item["image"] + (1 - item["mask"]) * item["background"]
        scale = exposure_scale(photo[None], item["mask"][None])
        srgb = (srgb_encode((photo[None] * scale).clamp(0, 1))[0].permute(1, 2, 0).numpy() * 255 + 0.5).astype(np.uint8)
        truth = load_scene(sample)
        h, w = truth.mask.shape
        cam = Camera(w, h)
        start = time.perf_counter()
        found = landmarks(srgb)
        row = {"sample": sample.name}
        if found is None:
            row["found"] = False
        else:
            fit = fit_body(*found, cam)
            row["seconds"] = round(time.perf_counter() - start, 2)
            row["reprojection_px"] = fit["reprojection_px"]
            depth, _, mask, _ = rasterize(cam, fit["vertices"], vertex_normals(fit["vertices"], fit["faces"]),
                                          np.zeros((len(fit["vertices"]), 8)), fit["faces"])
            row["found"] = True
            row["fitted"] = _scores(depth, mask, truth)
        seed = json.loads((sample / "sample.json").read_text())["seed"]
        prior = body_prior(seed, h, np.random.default_rng([seed, 0xB0D7]), json.loads((sample / "meta.json").read_text()))
        row["experiment_prior"] = _scores(prior["depth"], prior["mask"], truth)
        row["flat"] = _scores(np.full_like(truth.depth, float(np.median(truth.depth[truth.mask]))), truth.mask, truth)
        rows.append(row)
        if progress is not None:
            progress("people", n + 1, len(people))
    found = [r for r in rows if r["found"]]

    def mean(key, sub):
        values = [r[key][sub] for r in (found if key == "fitted" else rows) if r.get(key) and r[key][sub] is not None]
        return float(np.mean(values)) if values else None

    summary = {"people": len(rows), "landmarks_found": len(found),
               "depth_l1_cm": {k: mean(k, "depth_l1_cm") for k in ("fitted", "experiment_prior", "flat")},
               "iou": {k: mean(k, "iou") for k in ("fitted", "experiment_prior")},
               "reprojection_px": float(np.mean([r["reprojection_px"] for r in found])) if found else None,
               "seconds_per_fit": float(np.median([r["seconds"] for r in found])) if found else None}
    result = {"data": str(data), "summary": summary, "people": rows}
    if output:
        write_text(output, json.dumps(result, indent=1) + "\n")
    return result
