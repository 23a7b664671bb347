"""Make the bundled sample scene ``assets/sample_scene/``: a clothed person, rendered exactly.

What it does
------------
1. Poses a human body with the ``anny`` package (``pip install anny==0.6.2 -c constraints.txt``, the
   ``data`` extra; code Apache-2.0, body data from MakeHuman, CC0) in its ``notoes`` topology (feet
   without toes, for shoes), adding eyeballs (that topology leaves the sockets empty): a standing
   figure with the arms slightly away from the body, elbows a little bent, the left knee bent
   (weight on the right leg) and the head turned a little, so that arms shade the torso and the legs
   shade each other. Clothes and hair get some thickness: the body under the cloth is smoothed
   along the normals and each region stands off the skin by a few millimetres (``STANDOFF``).
2. Places it in the project's camera (``viewer.scene.camera.Camera``: 512x512, 50 mm lens on a 36 mm
   sensor, camera at the origin looking along -z, y up), turned ``--turn`` degrees about the vertical,
   its centre ``--distance`` metres in front of the camera, scaled uniformly so that it spans
   ``--fill`` of the image height (feet near the bottom, head near the top). A real-size person at
   4 m spans only about 60 % of this frame; scaling the body (1.37x) and keeping 4 m gives exactly
   the image of a real-size (1.83 m) person at about 2.9 m, with the depth values the project's
   convention expects (subject centre at ~4 m, as a depth network's output). The scale is printed.
3. Rasterizes the mesh with moderngl (headless EGL, RGBA32F render targets and a depth buffer, no
   supersampling, so nothing is averaged across silhouettes) with ``Camera.projection_matrix``:
   depth = view-space -z of the visible surface at each pixel centre (the value
   ``Camera.unproject`` inverts), normals = smooth area-weighted vertex normals interpolated and
   renormalized, in camera space; mask = covered pixels. The same pass interpolates the rest-pose
   position and a few skinning-weight sums of each vertex.
4. Makes the materials per pixel, procedurally, from those interpolated rest-pose fields (no
   textures ship with anny): a striped shirt with short sleeves, denim-like trousers with a belt,
   skin on the face, neck, forearms and hands, shoes with light soles, short dark hair, eyes.
   Albedo is linear RGB; specular / roughness follow the Disney convention of docs/conventions.md.
5. Checks the depth map against rays cast through pixel centres (as ``Camera.unproject`` defines
   them) into the mesh, writes the bundle with ``viewer.scene.bundle.save_scene``, loads it back with
   ``viewer.scene.bundle.load_scene`` (which validates it), compares the stored normals with normals computed from the depth map by
   finite differences (median angle printed), and writes a contact sheet of the maps (``--sheet``).

The bundled asset was produced from the project root with::

    .venv/bin/python tools/make_sample_scene.py -o assets/sample_scene --size 512

The first construction of the anny model takes one to two minutes and builds a ~1.7 GB cache in
``ANNY_CACHE_DIR`` (default ``~/.cache/anny``; keep it out of the repository); later runs take
about 6 seconds. The output is deterministic (fixed noise seeds).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from viewer.lab.data.geometry import vertex_normals  # noqa: E402
from viewer.lab.data.humans import build_body, dress, place_in_camera, rasterize  # noqa: E402
from viewer.lab.data.materials import make_materials  # noqa: E402
from viewer.scene.bundle import Scene, load_scene, save_scene  # noqa: E402
from viewer.scene.camera import Camera  # noqa: E402
from viewer.scene.resampling import depth_normal_angle  # noqa: E402

T0 = time.perf_counter()


def log(msg: str) -> None:
    print(f"[{time.perf_counter() - T0:6.1f} s] {msg}", flush=True)


# ----------------------------------------------------------------------------------------------
# Body
# ----------------------------------------------------------------------------------------------

# anny's phenotypes: gender 0 = male, 1 = female; age 2/3 = young adult, 1 = old
PHENOTYPE = dict(gender=0.15, age=0.7, muscle=0.55, weight=0.5, height=0.45, proportions=0.3)

# Local rotations (rotation vectors in radians, anny's world-aligned "local-ref" axes: x = the
# body's left, y = its back, z = up). Identity is anny's rest A-pose.
POSE = {
    # arms down to ~15 degrees from the body, elbows slightly bent, palms towards the thighs
    "upperarm01.L": (0.0, 0.50, 0.0),
    "upperarm01.R": (0.0, -0.50, 0.0),
    "lowerarm01.L": (0.55, 0.0, 0.25),
    "lowerarm01.R": (0.55, 0.0, -0.25),
    # weight on the right leg: the left knee bent and forward, the left heel lifted a little
    "upperleg01.L": (-0.30, 0.0, -0.08),
    "lowerleg01.L": (0.55, 0.0, 0.0),
    "foot.L": (-0.18, 0.0, 0.0),
    "upperleg01.R": (0.0, 0.04, 0.0),
    # a slight sway of the hips and shoulders, the head turned and tilted a little
    "spine03": (0.0, -0.03, 0.0),
    "spine01": (0.03, 0.02, 0.0),
    "neck01": (0.05, 0.0, 0.0),
    "head": (0.0, 0.05, 0.18),
}

# ----------------------------------------------------------------------------------------------
# Verification
# ----------------------------------------------------------------------------------------------


def ray_cast_check(cam: Camera, pos: np.ndarray, faces: np.ndarray, depth: np.ndarray, mask: np.ndarray,
                   count: int = 200, seed: int = 0) -> float:
    """Largest |depth - ray-cast depth| (metres) over ``count`` random mask pixels: the ray through
    each pixel centre (u, v) = (j + 0.5, i + 0.5) is intersected with every triangle (Moller-Trumbore)
    and the nearest hit's -z compared with the depth map."""
    rng = np.random.default_rng(seed)
    rows, cols = np.nonzero(mask)
    pick = rng.choice(len(rows), size=min(count, len(rows)), replace=False)
    a, b, c = pos[faces[:, 0]], pos[faces[:, 1]], pos[faces[:, 2]]
    e1, e2 = b - a, c - a
    f = cam.focal_px
    cx, cy = cam.center
    worst = 0.0
    for i, j in zip(rows[pick], cols[pick]):
        d = np.array([(j + 0.5 - cx) / f, -(i + 0.5 - cy) / f, -1.0])  # ray with unit -z speed
        pv = np.cross(d, e2)
        det = (e1 * pv).sum(1)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = -a
        u = (tv * pv).sum(1) * inv
        qv = np.cross(tv, e1)
        v = (qv * d).sum(1) * inv
        t = (e2 * qv).sum(1) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        if hit.any():
            worst = max(worst, abs(float(t[hit].min()) - float(depth[i, j])))
        else:  # a pixel on the silhouette: the ray grazes an edge
            worst = max(worst, float("inf"))
    return worst


def contact_sheet(scene: Scene, angle: np.ndarray, valid: np.ndarray, path: Path) -> Path:
    from PIL import Image, ImageDraw

    from viewer.files.imageio import linear_to_srgb

    m = scene.mask
    d = scene.depth
    dmin, dmax = float(d[m].min()), float(d[m].max())
    depth_vis = np.where(m, 1.0 - (d - dmin) / max(dmax - dmin, 1e-6) * 0.85, 0.0)
    light = np.array([-0.45, 0.55, 0.7])
    light /= np.linalg.norm(light)
    shade = np.clip((scene.normal * light).sum(-1), 0.0, None)
    shaded = linear_to_srgb(np.clip(scene.albedo * (0.15 + 1.2 * shade[..., None]), 0.0, 1.0))
    ang_vis = np.where(valid, np.clip(angle / 30.0, 0.0, 1.0), 0.0)
    panels = [
        ("albedo (sRGB)", linear_to_srgb(scene.albedo)),
        ("normal", np.where(m[..., None], scene.normal * 0.5 + 0.5, 0.0)),
        (f"depth {dmin:.2f}-{dmax:.2f} m", depth_vis),
        ("roughness", scene.roughness),
        ("specular", scene.specular),
        ("mask", m.astype(np.float32)),
        ("Lambert preview", shaded),
        ("|n - n(depth)| (0-30 deg)", ang_vis),
    ]
    h, w = m.shape
    cols, rows = 4, 2
    sheet = Image.new("RGB", (cols * w, rows * (h + 18)), (40, 40, 40))
    draw = ImageDraw.Draw(sheet)
    for k, (title, img) in enumerate(panels):
        img = np.asarray(img, dtype=np.float32)
        if img.ndim == 2:
            img = np.repeat(img[..., None], 3, axis=-1)
        tile = Image.fromarray((np.clip(img, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8))
        r, c = divmod(k, cols)
        sheet.paste(tile, (c * w, r * (h + 18) + 18))
        draw.text((c * w + 4, r * (h + 18) + 3), title, fill=(230, 230, 230))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)
    return path


# ----------------------------------------------------------------------------------------------


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", default=str(ROOT / "assets" / "sample_scene"), help="bundle directory to write")
    ap.add_argument("--size", type=int, default=512, help="image width and height in pixels (default 512)")
    ap.add_argument("--distance", type=float, default=4.0, help="depth of the body's centre in metres (default 4)")
    ap.add_argument("--turn", type=float, default=15.0, help="turn of the body about the vertical, degrees (default 15)")
    ap.add_argument("--fill", type=float, default=0.9, help="fraction of the image height the body spans (default 0.9)")
    ap.add_argument("--sheet", default="out/sample_scene_sheet.png", help="contact sheet PNG of the maps ('' for none)")
    args = ap.parse_args(argv)

    cam = Camera(args.size, args.size, distance=args.distance)
    log("building the anny body (the first time on a machine takes one to two minutes)")
    verts, faces, fields, heads, rest = build_body(PHENOTYPE, POSE)
    log(f"posed body with eyeballs: {len(verts)} vertices, {len(faces)} triangles, height {np.ptp(verts[:, 2]):.3f} m")
    verts = dress(verts, faces, fields, heads, rest)
    log("dressed: cloth smoothed and given thickness")

    pos, rot, scale = place_in_camera(verts, cam, args.distance, args.turn, args.fill)
    nrm = vertex_normals(pos, faces)
    log(f"placed in the camera: scale {scale:.3f} (same image as a real-size body at "
        f"{args.distance / scale:.2f} m), depth {-pos[:, 2].max():.3f}-{-pos[:, 2].min():.3f} m, turned {args.turn:g} deg")

    depth, normal, mask, attrs = rasterize(cam, pos, nrm, fields, faces)
    rows, cols = np.nonzero(mask)
    log(f"rasterized {args.size}x{args.size}: {int(mask.sum())} pixels in the mask, rows {rows.min()}-{rows.max()}, "
        f"columns {cols.min()}-{cols.max()}, depth {depth[mask].min():.3f}-{depth[mask].max():.3f} m")

    err = ray_cast_check(cam, pos, faces, depth, mask)
    log(f"depth map vs ray casting through 200 pixel centres: largest difference {err * 1000:.3f} mm")
    if not err < 1e-3:
        print("error: the depth map disagrees with Camera.unproject's rays", file=sys.stderr)
        return 1

    albedo, spec, rough, regions = make_materials(attrs, mask, heads, rest)
    total = max(int(mask.sum()), 1)
    log("materials: " + ", ".join(f"{k} {100.0 * v.sum() / total:.2g} %" for k, v in regions.items())
        + f"; albedo {albedo[mask].min():.3f}-{albedo[mask].max():.3f}")

    scene = Scene(albedo=albedo, specular=spec, roughness=rough, normal=normal, depth=depth.astype(np.float32),
                  mask=mask, camera=cam).validate()
    out = save_scene(scene, args.out)
    size = sum(f.stat().st_size for f in Path(out).iterdir() if f.is_file())
    log(f"wrote {out} ({size / 1e6:.2f} MB): " + ", ".join(sorted(f.name for f in Path(out).iterdir())))

    # verification: load it back (validates), normals against the depth geometry
    loaded = load_scene(out)
    err = max(float(np.abs(loaded.depth - scene.depth).max()), float(np.abs(loaded.normal - scene.normal).max()))
    assert np.array_equal(loaded.mask, scene.mask), "mask changed on the round trip"
    assert err < 1e-5, f"depth/normal changed on the round trip by {err}"
    ang, valid = depth_normal_angle(loaded)
    med = float(np.median(ang[valid]))
    p90 = float(np.percentile(ang[valid], 90))
    facing = float((loaded.normal[loaded.mask][:, 2] > 0.0).mean())
    log(f"loaded back and validated; normals vs depth-map normals over {int(valid.sum())} pixels: "
        f"median {med:.2f} deg, 90th percentile {p90:.2f} deg; n.z > 0 on {100.0 * facing:.1f} % of the mask")
    if med > 10.0:
        print(f"error: the normals disagree with the depth map (median {med:.2f} deg > 10 deg)", file=sys.stderr)
        return 1
    if args.sheet:
        log(f"contact sheet: {contact_sheet(loaded, ang, valid, args.sheet)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
