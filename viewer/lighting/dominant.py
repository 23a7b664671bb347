"""The dominant light of a set of area lights: the strongest with those near it, since a fit splits a
sun over several lights (the contact shadow's sky share, :mod:`viewer.plate.contact`; the plates
bench's dominant direction)."""

from __future__ import annotations

import numpy as np

from viewer.lighting.envmap import LUMINANCE
from viewer.scene.area_lights import AreaLights

CLUSTER_DEG = 20.0  # lights this near the strongest are one light with it (a fit splits a sun over several)


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
