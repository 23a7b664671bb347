"""The person's shadow on the ground against a ray tracer (``relight bench ground``).

The sample person's depth mesh stands on a white diffuse plane at its lowest point (the plane the
engine's ground pass assumes); Mitsuba renders the plane's shadowed diffuse with the person and
without it under the same map, and their ratio on the plane is the share of the ground's light left
(truth). The engine's ``1 - read_ground_shadow()`` is that share as the display uses it. Errors are
the mean absolute difference over the plane's pixels the person does not cover, within the region
either puts in shadow (ratio below 0.98), for each shadow method; times are the ground pass's own
(``EngineOptions.profile``), median of repeats. Two lightings: one Gaussian area light (a low sun,
where the engine's light is the map's light exactly) and the bundled mountain map (the engine with
its 16 fitted area lights, the truth with the whole map).
"""

from __future__ import annotations

import json
import time

import numpy as np

from viewer.files.imageio import write_text
from viewer.gl import Engine, EngineOptions
from viewer.lab.bench.contact import gaussian_light
from viewer.lighting.envmap import EnvMap, load_envmap
from viewer.resize import resize
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.area_lights import AreaLights, load_lights
from viewer.scene.bundle import load_scene
from viewer.scene.ground import GroundPlane, ground_plane
from viewer.scene.look import Look
from viewer.scene.resampling import resample_scene
from viewer.scene.shadow_space import ANGULAR_SIGMA

SUN = np.array([0.6, 0.45, 0.66]) / np.linalg.norm([0.6, 0.45, 0.66])  # low, from the right and in front
SUN_SIGMA = 3.0  # 256-px units (~5 degrees)
METHODS = ("hard", "csm", "pcss")
IN_SHADOW = 0.98
CONTACT_RADIUS = 0.25  # metres: the contact region, the ground around the feet


def plane_ratio(scene, env: EnvMap, plane: GroundPlane, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """(ratio (H, W), plane (H, W) bool): the ground plane's shadowed diffuse with the person over
    without it, and where the plane is seen uncovered by the person."""
    from viewer.lab.data.reference import bundle_mesh, camera_sensor, direct_scene, envmap_emitter, mi_mesh, mitsuba

    mi = mitsuba()
    white = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}})
    far = 200.0
    n = np.asarray(plane.normal, np.float64)
    side = np.cross(n, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    depth = np.cross(side, n)  # along the view axis, on the plane
    centre = n * plane.offset
    quad = np.array([centre + far * (a * side + b * depth) for a, b in ((-1, 1), (1, 1), (1, -1), (-1, -1))])
    up = np.tile(n, (4, 1))
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    m = bundle_mesh(scene)
    images = []
    for with_person in (True, False):
        items = direct_scene(camera_sensor(mi, scene, spp), envmap_emitter(mi, env))
        items["ground"] = mi_mesh(mi, "ground", quad, up, faces, white)
        if with_person:
            items["person"] = mi_mesh(mi, "person", m.vertices, m.normals, m.triangles, white)
        images.append(np.array(mi.render(mi.load_dict(items), spp=spp), dtype=np.float32)[..., :3].mean(axis=-1))
    shadowed, open_ground = images
    plane = (open_ground > 1e-6) & ~scene.mask
    return np.where(plane, shadowed / np.maximum(open_ground, 1e-12), 1.0), plane


def contact_region(scene, plane: GroundPlane, radius: float) -> np.ndarray:
    """(H, W) bool: the pixels whose point on ``plane`` lies within ``radius`` metres of a foot's contact."""
    view = scene.camera.view_directions().astype(np.float64)  # (H, W, 3), z = -1
    facing = view @ plane.normal
    t = np.where(facing < -1e-6, plane.offset / np.where(facing < -1e-6, facing, -1.0), np.inf)
    points = view * t[..., None]
    if not len(plane.contacts):
        return np.zeros(t.shape, bool)
    d = np.min(np.linalg.norm(points[:, :, None, :] - plane.contacts[None, None].astype(np.float64), axis=-1), axis=-1)
    return np.isfinite(t) & (d <= radius)


def engine_ratio(ctx, scene, lights: AreaLights, method: str, repeats: int) -> tuple[np.ndarray, float]:
    """(the engine's share of the ground's light left (H, W) at the work resolution, ground pass
    ms median)."""

    eng = Engine(ctx, scene, EngineOptions(soft="csm" if method == "hard" else method, profile=True))
    try:
        eng.set_lights(lights)
        look = Look(background="color", shadows="hard" if method == "hard" else "soft", ground=True)
        eng.set_look(look)
        eng.render()
        occ = eng.output.read_ground_shadow().mean(axis=-1)
        times = []
        for _ in range(repeats):  # the ground alone: off and on again redoes only the ground pass and the display
            eng.set_look(look.replace(ground=False))
            eng.render()
            eng.kit.timings.clear()
            eng.set_look(look)
            eng.render()
            times.append(1000.0 * sum(eng.kit.timings["ground_shadow"]))
    finally:
        eng.release()
    left = 1.0 - resize(occ, (scene.width, scene.height), "linear")
    return left, float(np.median(times))


def run_ground_benchmark(output: str, size: int = 256, spp: int = 256, repeats: int = 7) -> dict:
    from viewer.gl import create_headless_context
    from viewer.gl.context import describe

    ctx = create_headless_context()
    scene = resample_scene(load_scene(sample_scene_dir()), size)
    maps = asset_dir() / "envmaps"
    cases = {
        "low sun": (gaussian_light(SUN_SIGMA * ANGULAR_SIGMA, direction=SUN),
                    AreaLights(SUN[None].astype(np.float32), [SUN_SIGMA], [[1.0, 1.0, 1.0]])),
        "mountain map": (load_envmap(maps / "immenstadter_horn_256.hdr"), load_lights(maps / "immenstadter_horn_256.lights.json")),
        "studio map": (load_envmap(maps / "studio_small_03_256.hdr"), load_lights(maps / "studio_small_03_256.lights.json")),
    }
    plane = ground_plane(scene)
    rows = []
    for name, (env, lights) in cases.items():
        results = {m: engine_ratio(ctx, scene, lights, m, repeats) for m in METHODS}
        t0 = time.perf_counter()
        truth, seen = plane_ratio(scene, env, plane, spp)
        seconds = time.perf_counter() - t0
        near = seen & contact_region(scene, plane, CONTACT_RADIUS)
        for method, (left, ms) in results.items():
            region = seen & ((truth < IN_SHADOW) | (left < IN_SHADOW))
            err = float(np.abs(left - truth)[region].mean()) if region.any() else 0.0
            contact = float(np.abs(left - truth)[near].mean()) if near.any() else 0.0
            rows.append({"lighting": name, "method": method, "mae": err, "contact_mae": contact,
                         "contact_left_truth": float(truth[near].mean()) if near.any() else 1.0,
                         "contact_left_engine": float(left[near].mean()) if near.any() else 1.0, "ground_pass_ms": ms,
                         "shadow_pixels_truth": int((seen & (truth < IN_SHADOW)).sum()),
                         "shadow_pixels_engine": int((seen & (left < IN_SHADOW)).sum()),
                         "darkest_truth": float(truth[seen].min()), "darkest_engine": float(left[seen].min()),
                         "reference_seconds": round(seconds, 1)})
            print(f"{name}, {method}: contact region (within {CONTACT_RADIUS * 100:.0f} cm of the feet) mean |error| "
                  f"{contact:.3f}, light left {left[near].mean():.2f} (truth {truth[near].mean():.2f})", flush=True)
            print(f"{name}, {method}: mean |error| {err:.3f} of the ground's light over the shadow; ground pass "
                  f"{ms:.1f} ms; darkest {left[seen].min():.2f} (truth {truth[seen].min():.2f})", flush=True)
    out = {"machine": describe(ctx), "size": size, "spp": spp, "repeats": repeats,
           "method": "the sample person's depth mesh on a white ground plane (viewer.scene.ground: through the feet's contacts); "
                     "truth: Mitsuba's shadowed "
                     "diffuse of the plane with the person over without (direct light, the whole map); engine: "
                     "1 - read_ground_shadow(), bilinear to the work size; error: mean |difference| over plane pixels "
                     "uncovered by the person where either is below 0.98; time: the ground pass (profile), median",
           "rows": rows}
    path = write_text(output, json.dumps(out, indent=1) + "\n")
    print(f"wrote {path}")
    return out
