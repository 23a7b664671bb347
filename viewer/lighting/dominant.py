"""The dominant light of a set of area lights: the strongest with those near it, since a fit splits a
sun over several lights (the contact shadow's sky share, :mod:`viewer.plate.contact`; the plates
bench's dominant direction); and of a map itself (:func:`map_dominant_light`: its brightest direction after a
``BRIGHTEST_BLUR_DEG`` blur and the share of its light within ``CLUSTER_DEG`` of it: what ``relight plate-light``
says of the light it read, with no fit to wait for; ``relight bench plates`` measures directions so)."""

from __future__ import annotations

import numpy as np

from viewer.lighting.envmap import LUMINANCE
from viewer.resize import resize
from viewer.scene.area_lights import AreaLights

CLUSTER_DEG = 20.0  # lights this near the strongest are one light with it (a fit splits a sun over several)
DOMINANT_SHARE = 0.3  # of the lights' summed luminance: a light this strong is a dominant one (a sun, a lamp)
BRIGHTEST_BLUR_DEG = 5.0  # a map is blurred by this before its brightest direction is taken
BRIGHTEST_HEIGHT = 128  # rows a map is brought to (by area) before that blur


def strongest_group(lights: AreaLights, weights: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """(the direction of the lights' strongest, with those within ``CLUSTER_DEG`` of it, weighted; their
    share of the lights' summed weight): a sun a fit split over several lights counts as one. The
    weights are each light's luminance unless given (a light's irradiance on the ground, say)."""
    w = (np.asarray(lights.intensity, np.float64) @ LUMINANCE.astype(np.float64) if weights is None
         else np.asarray(weights, np.float64))
    dirs = np.asarray(lights.direction, np.float64)
    if not len(w) or float(w.sum()) <= 0.0:
        return np.array([0.0, 1.0, 0.0]), 0.0
    near = dirs @ dirs[int(np.argmax(w))] >= np.cos(np.radians(CLUSTER_DEG))
    direction = (dirs[near] * w[near, None]).sum(axis=0)
    return direction / max(float(np.linalg.norm(direction)), 1e-30), float(w[near].sum() / float(w.sum()))


def brightest_direction(pixels: np.ndarray) -> np.ndarray:
    """The unit direction (the map's frame) of an equirectangular map's brightest luminance after a
    ``BRIGHTEST_BLUR_DEG`` Gaussian blur on the sphere: where its dominant light is, however a fit would split it."""
    return _brightest(pixels)[0]


def _brightest(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the brightest direction, the map's luminance at ``BRIGHTEST_HEIGHT`` rows, its texels' directions)."""

    from viewer.lighting.envmap import pixel_directions
    from viewer.scene.backdrop import blurred_map

    small = resize(np.ascontiguousarray(pixels, np.float32), (2 * BRIGHTEST_HEIGHT, BRIGHTEST_HEIGHT), "area")
    dirs = pixel_directions(BRIGHTEST_HEIGHT, 2 * BRIGHTEST_HEIGHT)
    lum = blurred_map(small, np.radians(BRIGHTEST_BLUR_DEG)) @ LUMINANCE.astype(np.float32)
    return dirs[np.unravel_index(int(np.argmax(lum)), lum.shape)], small @ LUMINANCE.astype(np.float32), dirs


def _map_share(pixels: np.ndarray) -> tuple[np.ndarray, float]:
    """(a map's brightest direction, the share of its light (luminance over solid angle) within ``CLUSTER_DEG`` of it)."""
    from viewer.lighting.envmap import solid_angles

    direction, lum, dirs = _brightest(pixels)
    flux = lum * solid_angles(*lum.shape)[:, None]
    total = float(flux.sum())
    return direction, float(flux[dirs @ direction >= np.cos(np.radians(CLUSTER_DEG))].sum()) / total if total > 0.0 else 0.0


def map_dominant_light(pixels: np.ndarray, pitch: float = 0.0) -> tuple[tuple[float, float, float] | None, str]:
    """(azimuth, elevation, share) in degrees of an equirectangular map's dominant light, or None without one, and
    one line saying it: its brightest direction (:func:`brightest_direction`) when the texels within ``CLUSTER_DEG``
    of it hold ``DOMINANT_SHARE`` or more of its light, in the frame of a camera looking ``pitch`` degrees up (the
    azimuth from where it looks, to the right positive; the elevation above the horizon, its tilt undone); else
    how much the brightest direction holds."""
    direction, share = _map_share(pixels)
    if share < DOMINANT_SHARE:
        return None, (f"no dominant light: the brightest direction, with what is within {CLUSTER_DEG:g} degrees of it, "
                      f"holds {100 * share:.0f} % of the light (a sun or a lamp holds {100 * DOMINANT_SHARE:.0f} % or more): "
                      "no one direction leads")
    azimuth, elevation, share = found = _levelled(direction, pitch, share)
    side = "straight ahead of" if abs(azimuth) < 0.5 else f"{abs(azimuth):.0f} degrees to the {'right' if azimuth > 0 else 'left'} of"
    behind = " (behind the camera)" if abs(azimuth) > 90 else ""
    return found, (f"the dominant light ({100 * share:.0f} % of the light) comes from {side} where the camera looks{behind}, "
                   f"{abs(elevation):.0f} degrees {'above' if elevation >= 0 else 'below'} the horizon")


def _levelled(direction: np.ndarray, pitch: float, share: float) -> tuple[float, float, float]:
    """(azimuth, elevation, share) of ``direction`` in a camera's frame, the camera's tilt ``pitch`` undone."""
    from viewer.scene.area_lights import rotation_matrix

    x, y, z = (float(v) for v in rotation_matrix(0.0, pitch) @ direction)
    return float(np.degrees(np.arctan2(x, -z))), float(np.degrees(np.arcsin(np.clip(y, -1.0, 1.0)))), share
