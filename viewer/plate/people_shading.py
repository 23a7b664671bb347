"""Where the plate's sun is, from how its people are shaded (each person a light probe).

A person standing in a sun is bright on the side that faces it and, across each limb and the torso, brightest
where the surface turns to it; under a sky alone they are shaded evenly. The plate's people
(:attr:`viewer.plate.loader.Plate.people`: their segmentation) are read as upright cylinders, row by row:
each run of a row across the segmentation (a leg, an arm, the torso, the head) is a cylinder's cross-section,
whose normal at ``x`` is ``((x - c) / r, 0, sqrt(1 - ((x - c) / r)^2))`` in the camera's frame (``c`` the run's
middle, ``r`` half its width), the shape from the silhouette of the image-based material editing of Khan et
al. (2006) and of Lopez-Moreno et al.'s (2010) light detection. Each run's albedo is its own (a sleeve, a
trouser leg): its log luminance is fitted up to an offset by ``log(1 + k max(0, n . l))``, a light from the
horizontal direction ``l`` ``k`` times the even light, over every azimuth (``STEP_DEG`` apart) and ``k`` of
``STRENGTHS``, all the people at once (their errors summed). The sun is believed where the best fit leaves at
most ``EXPLAINED`` of the error of even light. The cylinders have no slope: the elevation is not read here
(the shadows' where they say it, else ``viewer.plate.shadows.TYPICAL_ELEVATION``).

What it cannot do: a figure in front of a bright sun is read as rim-lit from either side; a garment's pattern
across a limb (a stripe down a sleeve) looks like shading; a crouching or lying person is no set of upright
cylinders. The networks' normals and albedo (the product's photo-lighting fit on each person, as a photo's
bundle has) would read these better at seconds a person: not done yet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viewer.lighting.envmap import LUMINANCE
from viewer.plate.sky import bearing, camera_direction, world_at
from viewer.resize import resize

SAMPLE_WIDTH = 640  # pixels: the plate's longer side the people are read at
MIN_TALL = 0.12  # of the plate's height: a smaller person's rows are too few pixels across
MIN_RUN = 5  # pixels: a narrower run across a row (a finger, a strap) is no cylinder
STEP_DEG = 5.0
STRENGTHS = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0)  # the sun's light over the even light on a surface facing it
EXPLAINED = 0.8  # the best fit leaves at most this share of the even light's error: a sun is read
DARKEST = 1e-4  # linear luminance: darker pixels (black clothes, clipped to 0) say nothing of the light
MOST_SAMPLES = 6000  # a person's pixels read at most (whole rows, every n-th): the fit's time
MIN_SAMPLES, MIN_RUNS = 200, 10  # fewer pixels or runs left (not black) and a person says nothing of the light


@dataclass(frozen=True)
class ShadingSun:
    """The sun the people's shading says: ``azimuth`` (radians from where the camera looks, to the right
    positive; a light behind the camera at pi), ``strength`` (its light over the even light on a surface facing
    it), ``explained`` (the fit's error over the even light's), ``people`` (how many were read)."""

    azimuth: float
    strength: float
    explained: float
    people: int

    def direction_at(self, pitch: float) -> np.ndarray:
        """Its direction in the frame of the plate's camera tilted up by ``pitch`` (radians): the azimuth read, the
        elevation not (:data:`viewer.plate.shadows.TYPICAL_ELEVATION` taken)."""
        from viewer.plate.shadows import TYPICAL_ELEVATION

        return camera_direction(world_at(self.azimuth, TYPICAL_ELEVATION), pitch)


def sun_from_shading(plate) -> tuple[ShadingSun | None, str]:
    """(the sun the shading of ``plate``'s people says, or None; why, in words)."""

    w, h = plate.size
    scale = min(SAMPLE_WIDTH / max(w, h), 1.0)
    size = (max(round(w * scale), 1), max(round(h * scale), 1))
    lum = resize(plate.linear, size, "area") @ LUMINANCE.astype(np.float32)  # once for everyone
    samples = [s for s in (_samples(lum, person) for person in plate.people) if s is not None]
    if not samples:
        return None, "no sun read from the people's shading: no one found tall enough in the plate"
    azimuths = np.radians(np.arange(0.0, 360.0, STEP_DEG))
    errors, flat = np.zeros((len(azimuths), len(STRENGTHS))), 0.0
    for luminance, normals, runs in samples:
        e, f = _errors(luminance, normals, runs, azimuths)
        errors += e
        flat += f
    if flat <= 1e-9:  # every run even: nothing for a light from one side to explain
        return None, "no sun read from the people's shading: they are evenly lit across their limbs"
    i, j = np.unravel_index(int(np.argmin(errors)), errors.shape)
    explained = float(errors[i, j] / flat)
    if explained > EXPLAINED:
        return None, (f"no sun read from the people's shading: a light from one side explains {100 * (1 - explained):.0f} % of "
                      f"how {len(samples)} of them vary across their limbs ({100 * (1 - EXPLAINED):.0f} % is needed)")
    # the fit's azimuth is from the camera (+z); the plate's from where it looks (-z)
    azimuth = math.remainder(math.pi - float(azimuths[i]), 2.0 * math.pi)
    return (ShadingSun(azimuth, float(STRENGTHS[j]), round(explained, 3), len(samples)),
            f"a sun read from the shading of {len(samples)} of the plate's people: {bearing(world_at(azimuth, 0.0))} (it explains "
            f"{100 * (1 - explained):.0f} % of how they vary across their limbs beyond an even light)")


def _samples(plate_lum: np.ndarray, person) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(luminance, the cylinders' normals (N, 3) in the camera's frame, each sample's run) of ``person`` in the
    plate's luminance ``plate_lum`` (at ``SAMPLE_WIDTH``), or None when they are too small."""
    import cv2

    size = plate_lum.shape[1::-1]
    mask = resize(person.segmentation, size, "area") > 0.5
    mask = cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0  # the matte's edge mixes the background in
    rows = np.flatnonzero(mask.any(axis=1))
    if not len(rows) or rows[-1] - rows[0] < MIN_TALL * size[1]:
        return None
    x0, x1 = np.flatnonzero(mask.any(axis=0))[[0, -1]]
    y0, y1 = rows[0], rows[-1] + 1
    lum = plate_lum[y0:y1, x0:x1 + 1]
    values, normals, runs = [], [], []
    every = max(int(mask[y0:y1].sum()) // MOST_SAMPLES, 1)
    for y, row in enumerate(mask[y0:y1, x0:x1 + 1]):
        if y % every:
            continue
        edges = np.diff(np.concatenate([[0], row.astype(np.int8), [0]]))
        for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
            if b - a < MIN_RUN:
                continue
            across = (np.arange(a, b) - 0.5 * (a + b - 1)) / (0.5 * (b - a))
            values.append(lum[y, a:b])
            normals.append(np.stack([across, np.zeros_like(across), np.sqrt(np.clip(1.0 - across ** 2, 0.0, 1.0))], axis=-1))
            runs.append(np.full(b - a, len(runs)))
    if not values:
        return None
    luminance, normals, runs = np.concatenate(values), np.concatenate(normals), np.concatenate(runs)
    keep = luminance > DARKEST
    if keep.sum() < MIN_SAMPLES or len(np.unique(runs[keep])) < MIN_RUNS:  # a silhouette crushed to black says nothing
        return None
    _, runs = np.unique(runs[keep], return_inverse=True)  # the runs left, numbered from 0
    return luminance[keep], normals[keep], runs


def _errors(luminance: np.ndarray, normals: np.ndarray, runs: np.ndarray, azimuths: np.ndarray) -> tuple[np.ndarray, float]:
    """(the summed squared log error of every (azimuth, strength) fit, each run's offset fitted; the even light's)."""
    log = np.log(luminance)
    count = np.maximum(np.bincount(runs), 1)

    def error(model_log: np.ndarray) -> np.ndarray:  # (..., N) -> (...): each run's mean taken out
        residual = log - model_log
        means = np.stack([np.bincount(runs, weights=r) for r in residual.reshape(-1, residual.shape[-1])]) / count
        return np.sum((residual.reshape(-1, residual.shape[-1]) - means[:, runs]) ** 2, axis=-1).reshape(residual.shape[:-1])

    lights = np.stack([np.sin(azimuths), np.zeros_like(azimuths), np.cos(azimuths)], axis=-1)  # +z: from the camera's side
    facing = np.clip(lights @ normals.T, 0.0, None)  # (A, N)
    strengths = np.asarray(STRENGTHS)[None, :, None]
    return error(np.log1p(strengths * facing[:, None, :])), float(error(np.zeros((1, len(log))))[0])
