"""A body prior for the synthetic people, to measure what one is worth before fitting one to photos
(a body fitted to the photo as a depth/normal prior, kept only where it measurably helps).

At inference a prior would come from anny posed to MediaPipe's landmarks: the right pose up to the
landmarks' error, an average body shape, no clothes or hair. Here it is made the same way from
what the dataset knows: the person's own pose with every joint's rotation perturbed
(``POSE_NOISE`` radians per axis, about the error of single-image 3D pose estimates), an average
body (:data:`AVERAGE`: anny's phenotype at 0.5, an adult's age), unclothed, placed by the dressed person's own placement, and
rasterized into the sample's camera: depth, normal and mask (``body_prior.npz`` per sample).

This is an upper bound on what a fitted body can give (its placement is exact); if the networks
gain little from it, the fitting is not worth building.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viewer.scene.camera import Camera

POSE_NOISE = 0.08  # radians per rotation-vector axis (about 8 degrees per joint and axis)
AVERAGE = dict(gender=0.5, age=0.75, muscle=0.5, weight=0.5, height=0.5, proportions=0.5)
NOISY_BONES = ("upperarm01", "lowerarm01", "upperleg01", "lowerleg01")  # both sides
FILE = "body_prior.npz"


def body_prior(seed: int, size: int, rng: np.random.Generator, meta: dict | None = None) -> dict:
    """Depth (H, W; 0 outside), normal (H, W, 3) and mask of the prior body of dataset person ``seed``.
    ``meta``: the sample's ``meta.json``; the person is remade from the seed by today's generator,
    so a sample made by an older one (another pose for the same seed) is refused in one line."""
    from viewer.errors import InputError
    from viewer.lab.data.geometry import vertex_normals
    from viewer.lab.data.humans import build_body, dress, placement, rasterize
    from viewer.lab.data.people import person_draws

    phenotype, style, pose, outfit, turn, fill = person_draws(seed)
    if meta is not None and (meta.get("pose_style") != style or not np.isclose(meta.get("turn_degrees", np.nan), turn)):
        raise InputError(None, f"person {seed} was made by an older generator (its pose is not today's): no body prior for it")
    verts, faces, fields, heads, rest = build_body(phenotype, pose)
    dressed = dress(verts, faces, fields, heads, rest, outfit)
    cam = Camera(size, size)
    r, s, centre, t = placement(dressed, cam, cam.distance, turn, fill)
    noisy = dict(pose)
    for bone in [f"{b}.{side}" for b in NOISY_BONES for side in ("L", "R")] + ["spine03", "spine01", "neck01", "head"]:
        noisy[bone] = tuple(float(v) for v in np.asarray(pose.get(bone, (0.0, 0.0, 0.0))) + rng.normal(0.0, POSE_NOISE, 3))
    body, body_faces, _, _, body_rest = build_body(AVERAGE, noisy)
    # the average body has its own height: scale it to the person's standing height about anny's
    # origin (the root joint, where both skeletons start)
    body = body * (np.ptp(rest[:, 2]) / max(np.ptp(body_rest[:, 2]), 1e-6))
    pos = s * (body @ r.T - centre) + t
    depth, normal, mask, _ = rasterize(cam, pos, vertex_normals(pos, body_faces), np.zeros((len(pos), 8)), body_faces)
    return {"depth": depth.astype(np.float32), "normal": normal, "mask": mask}


def cached_body_prior(sample: Path, size: int) -> dict:
    """The prior of one dataset sample (its person's seed from ``sample.json``), made once and kept
    as ``body_prior.npz`` in it (made again when the kept one has another size)."""
    import json

    from viewer.files.imageio import atomic_path

    path = Path(sample) / FILE
    if path.is_file():
        with np.load(path) as z:
            kept = {k: z[k] for k in ("depth", "normal", "mask")}
        if kept["depth"].shape == (size, size):
            return kept
    seed = json.loads((Path(sample) / "sample.json").read_text())["seed"]
    meta = json.loads((Path(sample) / "meta.json").read_text())
    prior = body_prior(seed, size, np.random.default_rng([int(seed), 0xB0D7]), meta)
    with atomic_path(path) as tmp:  # a temporary name of this process's own: ranks may make it at once
        with open(tmp, "wb") as f:
            np.savez_compressed(f, depth=prior["depth"].astype(np.float16), normal=prior["normal"].astype(np.float16),
                                mask=prior["mask"])
    return cached_body_prior(sample, size)
