"""The dominant light of a set of area lights: the strongest with those near it, since a fit splits a
sun over several lights (the contact shadow's sky share, :mod:`viewer.plate.contact`; the plates
bench's dominant direction; what ``relight plate-light`` says of the light it read)."""

from __future__ import annotations

import numpy as np

from viewer.lighting.envmap import LUMINANCE
from viewer.scene.area_lights import AreaLights

CLUSTER_DEG = 20.0  # lights this near the strongest are one light with it (a fit splits a sun over several)
DOMINANT_SHARE = 0.3  # of the lights' summed luminance: a light this strong is a dominant one (a sun, a lamp)


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


def dominant_light(lights: AreaLights, pitch: float = 0.0) -> tuple[float, float, float] | None:
    """(azimuth, elevation, share) of the lights' dominant light (:func:`strongest_group` holding
    ``DOMINANT_SHARE`` or more of their luminance), in degrees, for lights in a camera's frame whose camera
    looks ``pitch`` degrees up (a plate's, read from its horizon): the azimuth from where the camera looks
    (-z), to the right positive, the elevation above the horizon; None without one."""
    from viewer.scene.area_lights import rotation_matrix

    direction, share = strongest_group(lights)
    if share < DOMINANT_SHARE:
        return None
    x, y, z = (float(v) for v in rotation_matrix(0.0, pitch) @ direction)  # levelled: the camera's tilt undone
    return float(np.degrees(np.arctan2(x, -z))), float(np.degrees(np.arcsin(np.clip(y, -1.0, 1.0)))), share


def dominant_light_line(lights: AreaLights, pitch: float = 0.0) -> str:
    """One line on where the light comes from (:func:`dominant_light`): its direction as the camera sees it
    and its share, or that there is none and how much the strongest holds."""
    found = dominant_light(lights, pitch)
    if found is None:
        share = strongest_group(lights)[1]
        return (f"no dominant light: the strongest, with those within {CLUSTER_DEG:g} degrees of it, holds {100 * share:.0f} % "
                f"of the light (a sun or a lamp holds {100 * DOMINANT_SHARE:.0f} % or more): no one direction leads")
    azimuth, elevation, share = found
    side = "straight ahead of" if abs(azimuth) < 0.5 else f"{abs(azimuth):.0f} degrees to the {'right' if azimuth > 0 else 'left'} of"
    behind = " (behind the camera)" if abs(azimuth) > 90 else ""
    return (f"the dominant light ({100 * share:.0f} % of the light) comes from {side} where the camera looks{behind}, "
            f"{abs(elevation):.0f} degrees {'above' if elevation >= 0 else 'below'} the horizon")
