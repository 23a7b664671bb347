"""Penumbra width at contact: the simplest scene where a real area light's shadow hardens near the
blocker and widens away from it. A square box face hangs at several heights over a plane, lit by
one Gaussian area light from the side; the width of the partial shadow on the plane beside the box
is measured on the engine's visibility (hard shadow maps, the paper's CSM, contact-hardening PCSS)
and on Mitsuba's ray-traced shadowed diffuse of a map that is black but for that light. Used by
``relight bench report`` (its own figure and table) and by tests/test_soft_shadows.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewer.gl import Engine, EngineOptions
from viewer.lab.scenes import plane_and_box
from viewer.lighting.envmap import EnvMap, pixel_directions
from viewer.scene.area_lights import AreaLights
from viewer.scene.shadow_space import ANGULAR_SIGMA

LIGHT = np.array([1.0, 0.3, 0.8]) / np.linalg.norm([1.0, 0.3, 0.8])  # from the right, towards the camera
SIGMA = 7.0  # 256-px units: an angular sigma of SIGMA * ANGULAR_SIGMA radians (~8 degrees)
PLANE_DEPTH = 4.0
BOX_HALF = 0.3  # metres
METHODS = ("hard", "csm", "pcss")


@dataclass(frozen=True)
class ContactConfig:
    heights: tuple = (0.05, 0.15, 0.3, 0.6)  # metres between the box's face and the plane
    size: int = 128  # pixels (22.5 mm per pixel at the plane)
    spp: int = 512  # reference samples per pixel


def gaussian_light(alpha: float, width: int = 1024, direction=LIGHT) -> EnvMap:
    """A map black but for a light of angular Gaussian sigma ``alpha`` (radians) towards ``direction``
    (unit)."""
    d = pixel_directions(width // 2, width)
    angle = np.arccos(np.clip(d @ np.asarray(direction), -1.0, 1.0))
    return EnvMap((np.exp(-0.5 * (angle / alpha) ** 2)[..., None] * np.ones(3)).astype(np.float32))


def penumbra(visibility: np.ndarray, box: np.ndarray) -> float:
    """Mean width (pixels) of the partial shadow (visibility in (0.15, 0.85)) on the plane beside the
    box, along the rows of the middle half of the box (the light comes from the right: the shadow
    falls to the left; the box's outline is left out, where pixels see both the plane and the box's side)."""
    rows = np.nonzero(box.any(axis=1))[0]
    left = np.nonzero(box.any(axis=0))[0].min()
    middle = rows[len(rows) // 4: 3 * len(rows) // 4]
    v = visibility[middle, : left - 1]
    return float(((v > 0.15) & (v < 0.85)).sum(axis=1).mean())


def penumbra_widths(ctx, config: ContactConfig = ContactConfig(), methods=METHODS) -> dict:
    """{"heights": [...], "pixel_mm": ..., method: [width in pixels per height], "truth": [...]}."""
    from viewer.lab.data.reference import render_bundle_reference

    out = {"heights": list(config.heights), "sigma": SIGMA, "angle_deg": float(np.degrees(SIGMA * ANGULAR_SIGMA)),
           "truth": [], **{m: [] for m in methods}}
    env = gaussian_light(SIGMA * ANGULAR_SIGMA)
    for h in config.heights:
        scene = plane_and_box(config.size, box_depth=PLANE_DEPTH - h, box_half=BOX_HALF, specular=0.0, albedo=1.0)
        on_plane = scene.depth > PLANE_DEPTH - 1e-3
        box = ~on_plane
        for method in methods:
            eng = Engine(ctx, scene, EngineOptions(soft="csm" if method == "hard" else method, shadow_step=1))
            try:
                eng.set_lights(AreaLights(LIGHT[None].astype(np.float32), [SIGMA], [[1.0, 1.0, 1.0]]))
                eng.render()
                v = eng.output.read_light(0)["visibility_hard" if method == "hard" else "visibility_soft"]
            finally:
                eng.release()
            out[method].append(penumbra(v, box))
        y = render_bundle_reference(scene, env, spp=config.spp, images=("diffuse_shadowed",))["diffuse_shadowed"].mean(axis=-1)
        out["truth"].append(penumbra(y / np.median(y[on_plane]), box))  # most of the plane is lit
    out["pixel_mm"] = float(1000.0 * PLANE_DEPTH / scene.camera.focal_px)
    return out


def contact_errors(widths: dict, methods=METHODS) -> dict:
    """Per method: the mean absolute width error (pixels) over the heights, and at the lowest one."""
    truth = np.array(widths["truth"])
    return {m: {"mean_abs_px": float(np.mean(np.abs(np.array(widths[m]) - truth))),
                "lowest_abs_px": float(abs(widths[m][0] - truth[0]))} for m in methods}
