"""The person matched to the plate's camera: the plate's defocus where the feet stand, and its grain.

A person rendered into a plate is as sharp and as clean as the renderer makes them; the plate is
not. Two measures of the plate, each from a well-known estimator:

- **defocus at the feet** (:func:`feet_blur`): the re-blur estimate of Zhuo and Sim (2011)
  (:func:`viewer.scene.backdrop.edge_blur`, the backdrop's own) over the plate around where the feet
  stand (as wide as the person is tall, from a quarter of their height above the feet to a twentieth
  below): the ground there is at the person's depth. Where that ground is too plain to tell (fewer
  than 50 edges: a smooth floor), the same rows across the whole plate (a level ground's depth is its
  row). The person's layer is blurred by that sigma. (Edges are the gradient's maxima across the edge,
  as Canny's: a maximum over all eight neighbours finds 10 points on a plate blurred by 3 pixels,
  and reads it as sharp: a soft plate would keep a crisp person.)
- **grain** (:func:`grain_levels`): Immerkaer's (1996) fast noise estimate, the mean absolute response
  of the Laplacian difference kernel (which cancels any plane and most smooth shading), over the
  plate's flatter half (its gradients below their median, so edges are not taken for noise), per
  channel, in 8-bit levels. Gaussian noise of that size is added to the person where they cover the
  plate, in the 8-bit picture (the EXR stays clean: compositors add their own grain).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from viewer.plate.placement import Placement
from viewer.scene.backdrop import edge_blur

NOISE_KERNEL = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
GRAIN_SEED = 47  # the grain is the same on every run of the same composite
GRAIN_TILE = 256  # pixels: the grain's pattern repeats this far apart, pinned to the plate's pixels


def grain_levels(srgb: np.ndarray) -> np.ndarray:
    """(3,) the plate's noise sigma per channel, in 8-bit levels (Immerkaer 1996, over its flatter half)."""
    import cv2

    img = srgb.astype(np.float32)
    grey = cv2.cvtColor(srgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
    gradient = np.hypot(cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3))
    flat = gradient[1:-1, 1:-1] <= np.median(gradient[1:-1, 1:-1])
    out = []
    for c in range(3):
        response = np.abs(cv2.filter2D(img[..., c], cv2.CV_32F, NOISE_KERNEL))[1:-1, 1:-1]
        out.append(math.sqrt(math.pi / 2.0) * float(response[flat].mean()) / 6.0 if flat.any() else 0.0)
    return np.array(out, np.float32)


def feet_blur(srgb: np.ndarray, place: Placement) -> float:
    """The plate's defocus sigma (pixels) around where the feet stand (:mod:`viewer.plate.match`)."""
    h, w = srgb.shape[:2]
    tall = place.height * h
    x, y = place.x * w, place.y * h
    region = np.zeros((h, w), bool)
    rows = slice(int(np.clip(y - 0.25 * tall, 0, h)), int(np.clip(y + 0.05 * tall, 0, h)))
    cols = slice(int(np.clip(x - 0.5 * tall, 0, w)), int(np.clip(x + 0.5 * tall, 0, w)))
    region[rows, cols] = True
    blur = edge_blur(srgb, region, unknown=None)
    if blur is None:  # the ground at the feet too plain to tell: the rows at their depth, the plate's whole width
        region[rows, :] = True
        blur = edge_blur(srgb, region, unknown=None)
    return 0.0 if blur is None else blur


def with_grain(srgb: np.ndarray, coverage: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """``srgb`` (H, W, 3) float in [0, 1] with Gaussian noise of ``levels`` (8-bit levels, per channel)
    added in proportion to ``coverage`` (H, W) in [0, 1]: the same noise at the same plate pixel on every
    run and every frame of a clip (a tile of ``GRAIN_TILE`` pixels, pinned to the plate, as the still
    plate's own grain is), added where the person is only."""
    out = np.clip(srgb, 0.0, 1.0)
    rows, cols = np.flatnonzero(coverage.any(axis=1)), np.flatnonzero(coverage.any(axis=0))
    if not len(rows):
        return out
    y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    noise = _grain_tile()[np.arange(y0, y1)[:, None] % GRAIN_TILE, np.arange(x0, x1)[None, :] % GRAIN_TILE]
    out[y0:y1, x0:x1] = np.clip(srgb[y0:y1, x0:x1] + noise * (levels / 255.0) * coverage[y0:y1, x0:x1, None], 0.0, 1.0)
    return out


@functools.cache
def _grain_tile() -> np.ndarray:
    """(GRAIN_TILE, GRAIN_TILE, 3) float32 unit Gaussian noise, the same in every process."""
    return np.random.default_rng(GRAIN_SEED).standard_normal((GRAIN_TILE, GRAIN_TILE, 3)).astype(np.float32)
