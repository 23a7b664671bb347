"""The contact shadow: the plate's ground around the person's feet darkened by the share of the sky the
person hides from it (ambient occlusion).

The engine's ground shadow is one shadow per area light cast by the person's front surface (a shell),
so under a soft light its darkest part lies right under the soles, which the person covers: the
ground beside and in front of the shoes, where a photographed person's contact shadow shows, stays
lit. Here each foot stands on the ground as a low box (the matte's columns whose lowest pixel is near
the feet, ``LEGS_BAND``, split where they part: its width; ``FOOT_LENGTH`` long away from the camera,
``FOOT_HEIGHT`` tall) under a leg (a column as wide as the foot, as tall as the person). A ground point
loses the cosine-weighted share ``dphi / 2 pi * h^2 / (h^2 + r^2)`` of its sky to each (the azimuth
``dphi`` it spans over a cosine-weighted hemisphere, up to its top ``h`` seen from ``r`` away); per
foot the larger of the box's and the leg's, summed over the feet, at most ``MAX_OCCLUSION``. Metres
come from the person's height (``PERSON_HEIGHT_M``) in plate pixels; the ground's foreshortening (a
metre towards the camera spans ``c`` times a metre across, ``c = camera height / distance``) from the
plate's horizon, ``c = (feet - horizon) / f`` (rows, a focal length of ``f`` pixels, a level camera),
else from a camera at eye height (``CAMERA_HEIGHT_M``), ``c = CAMERA_HEIGHT_M * T / (PERSON_HEIGHT_M
* f)`` for a person ``T`` pixels tall.

Only the sky's share of the ground's light is hidden so: under a sun the ground around the feet
keeps the sun's light (its shadow is the engine's), so the occlusion is scaled by :func:`sky_share`.
"""

from __future__ import annotations

import numpy as np

from viewer.plate.placement import CAMERA_HEIGHT_M, PERSON_HEIGHT_M

LEGS_BAND = 0.04  # of the person's height: a matte column whose lowest pixel is this near the feet stands on the ground
FOOT_LENGTH, FOOT_HEIGHT = 0.25, 0.08  # metres: a foot (a shoe) as a box on the ground, going away from the camera
REACH = 0.15  # of the person's height: the occlusion is computed this far from the feet (fading out, ``FADE``)
MAX_OCCLUSION = 0.5  # a ground point right against the person loses at most half its sky (as against a wall)
FADE = 0.5  # of the window's half size: the occlusion fades out (smoothly) from here to the window's edge
POINTS = 8  # of a foot's columns taken as its outline (every k-th)


def sky_share(lights) -> float:
    """The share of a level ground's light (its irradiance) that is not the strongest light's (with those
    near it: a sun a fit split over several, :func:`viewer.lighting.dominant.strongest_group`): what a
    contact shadow hides (1 under an overcast sky, ~0.1-0.5 under a clear sun). ``lights``: area
    lights in camera space (y up)."""
    from viewer.lighting.dominant import strongest_group

    up = np.clip(np.asarray(lights.direction, np.float64)[:, 1], 0.0, None)
    each = np.asarray(lights.intensity, np.float64).mean(axis=1) * up
    if not len(each) or float(each.sum()) <= 0.0:
        return 0.0
    return 1.0 - strongest_group(lights, each)[1]


def contact_shadow(alpha: np.ndarray, focal_px: float, sky: float, horizon_px: float | None = None) -> np.ndarray | None:
    """(H, W) float32 multiplier of the plate (1 where nothing is hidden) for the person whose matte in
    the plate is ``alpha`` (H, W), their feet on the ground, the plate's horizon at row ``horizon_px``
    (of ``alpha``'s rows; None: unknown, a camera at eye height assumed); None when nothing is to
    darken (no matte, no sky)."""
    person = alpha > 0.5
    if sky <= 0.0 or not person.any():
        return None
    rows = np.flatnonzero(person.any(axis=1))
    top, feet = int(rows[0]), int(rows[-1]) + 1
    tall = float(feet - top)
    cols = np.flatnonzero(person.any(axis=0))
    lowest = person.shape[0] - 1 - np.argmax(person[::-1, cols], axis=0)  # each column's lowest person pixel
    on_ground = lowest + 1 >= feet - LEGS_BAND * tall
    if not on_ground.any():
        return None
    per_m = tall / PERSON_HEIGHT_M  # plate pixels a metre, across, where the person stands
    if horizon_px is not None and feet > horizon_px:  # a level camera: the feet's depth below the horizon
        squash = (feet - horizon_px) / max(focal_px, 1.0)
    else:
        squash = CAMERA_HEIGHT_M * tall / (PERSON_HEIGHT_M * max(focal_px, 1.0))
    squash = min(max(squash, 0.02), 1.0)
    x_c, z_c = cols[on_ground], lowest[on_ground] + 1.0
    parts = np.split(np.arange(len(x_c)), np.flatnonzero(np.diff(x_c) > 2) + 1)  # the feet: runs of columns
    h, w = alpha.shape
    reach = REACH * tall
    y0, y1 = max(int(feet - reach * squash) - 1, 0), min(int(feet + reach * squash) + 2, h)
    x0, x1 = max(int(x_c.min() - reach) - 1, 0), min(int(x_c.max() + reach) + 2, w)
    out = np.ones((h, w), np.float32)
    if y0 >= y1 or x0 >= x1:
        return out
    gx = ((np.arange(x0, x1, dtype=np.float32) + 0.5) / per_m)[None, :, None]  # metres across
    gz = ((np.arange(y0, y1, dtype=np.float32) + 0.5) / (per_m * squash))[:, None, None]  # metres towards the camera
    occlusion = np.zeros((y1 - y0, x1 - x0), np.float32)
    for part in parts:
        take = part[:: max(len(part) // POINTS, 1)]
        fx = np.concatenate([x_c[take] + 0.5, [x_c[part[-1]] + 1.0], [x_c[part[0]]]]) / per_m
        fz = np.concatenate([z_c[take], [z_c[part[-1]]], [z_c[part[0]]]]) / (per_m * squash)
        fx, fz = np.concatenate([fx, fx]), np.concatenate([fz, fz - FOOT_LENGTH])  # its toes and its heels
        dx, dz = (fx - gx).astype(np.float32), (fz - gz).astype(np.float32)
        r = np.sqrt(dx * dx + dz * dz).min(axis=-1)
        centre = np.arctan2(dz.mean(axis=-1), dx.mean(axis=-1))[..., None]
        turn = (np.arctan2(dz, dx) - centre + np.pi) % (2.0 * np.pi) - np.pi  # azimuths about the foot's, in (-pi, pi]
        box = (turn.max(axis=-1) - turn.min(axis=-1)) / (2.0 * np.pi) * FOOT_HEIGHT ** 2 / (FOOT_HEIGHT ** 2 + r * r)
        width = (fx.max() - fx.min()) + 1.0 / per_m
        leg_r = np.hypot(gx[..., 0] - fx.mean(), gz[..., 0] - fz.mean())
        leg = np.arctan(width / (2.0 * leg_r + 1e-6)) / np.pi * PERSON_HEIGHT_M ** 2 / (PERSON_HEIGHT_M ** 2 + leg_r * leg_r)
        occlusion += np.maximum(box, leg)
    # faded out towards the window's edges (no step where the computed window ends)
    u = np.abs(np.arange(x0, x1) + 0.5 - 0.5 * (x_c.min() + x_c.max() + 1)) / (0.5 * (x_c.max() + 1 - x_c.min()) + reach)
    v = np.abs(np.arange(y0, y1) + 0.5 - feet) / max(reach * squash, 1.0)
    edge = np.clip((1.0 - np.maximum(u[None, :], v[:, None])) / (1.0 - FADE), 0.0, 1.0)
    out[y0:y1, x0:x1] = 1.0 - sky * np.minimum(occlusion, MAX_OCCLUSION) * edge * edge * (3.0 - 2.0 * edge)
    return out
