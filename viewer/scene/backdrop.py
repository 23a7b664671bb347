"""The backdrop behind the relit person: the photo's own background defocus, measured, and the
environment map blurred to match it.

A photo's background is usually out of focus; the map drawn sharp behind a relit person looks
pasted. ``photo_blur`` measures the photo's far background (above the middle of the person,
farther than a twentieth of their height from them) by the gradient ratio of Zhuo and Sim
(2011): at edges, the gradient over the gradient of the image re-blurred by a known Gaussian
gives the edge's own blur. ``Look.backdrop_blur`` "auto" blurs the map by that angle (as the
photo's camera sees it); a number of degrees sets it. ``blurred_map`` blurs an equirectangular
map by a Gaussian of a given angle on the sphere (wider in longitude towards the poles).
"""

from __future__ import annotations

import math

import numpy as np

from viewer.scene.look import MAX_BACKDROP_BLUR

REBLUR = 2.0  # pixels: the known Gaussian of the gradient ratio
PRESMOOTH = 1.0  # pixels: against the sensor's noise, taken back out of the estimate
EDGE_PERCENTILE = 95.0  # the strongest gradients of the far background are its edges
MIN_EDGES = 50  # fewer edges than this: the background is too plain to tell (no blur)
MAX_BLUR = math.radians(MAX_BACKDROP_BLUR)  # the largest backdrop blur (Look.backdrop_blur's bound)
BANDS = 32  # rows of latitude blurred alike (their longitude sigma differs by the cosine of latitude)


def photo_blur(photo: np.ndarray, alpha: np.ndarray) -> float:
    """The Gaussian sigma (pixels) of the photo's far background's defocus: :func:`edge_blur` over
    the background above the middle of the person, farther than a twentieth of their height from
    them (the ground near the feet is in focus); 0 when it has too few edges to tell."""
    import cv2

    person = alpha > 0.5
    rows = np.flatnonzero(person.any(axis=1))
    if rows.size == 0:
        return 0.0
    far = cv2.distanceTransform((~person).astype(np.uint8), cv2.DIST_L2, 5) > 0.05 * (rows[-1] - rows[0] + 1)
    far[(rows[0] + rows[-1]) // 2:] = False
    return edge_blur(photo, far)


def edge_blur(photo: np.ndarray, region: np.ndarray, unknown: float | None = 0.0) -> float | None:
    """The Gaussian sigma (pixels) of the defocus of ``photo`` (H, W, 3) uint8 over ``region`` (H, W)
    bool: the median over the region's strongest edges (maxima across the edge) of the re-blur estimate
    (Zhuo and Sim 2011); ``unknown`` when the region has too few edges to tell."""
    import cv2

    if not region.any():
        return unknown

    def gradient(x):
        return cv2.Sobel(x, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(x, cv2.CV_32F, 0, 1, ksize=3)

    grey = cv2.GaussianBlur(cv2.cvtColor(photo, cv2.COLOR_RGB2GRAY).astype(np.float32) / 255.0, (0, 0), PRESMOOTH)
    gx, gy = gradient(grey)
    g1, g2 = np.hypot(gx, gy), np.hypot(*gradient(cv2.GaussianBlur(grey, (0, 0), REBLUR)))
    strong = g1 >= max(float(np.percentile(g1[region], EDGE_PERCENTILE)), 1e-3)
    edges = region & strong & _across_edge_maxima(g1, gx, gy) & (g2 > 1e-4)
    ratio = g1[edges] / g2[edges]
    ratio = ratio[ratio > 1.0 + 1e-4]
    if ratio.size < MIN_EDGES:
        return unknown
    total = REBLUR / np.sqrt(ratio ** 2 - 1.0)
    return float(np.median(np.sqrt(np.maximum(total ** 2 - PRESMOOTH ** 2, 0.0))))


def _across_edge_maxima(g: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """(H, W) bool: where the gradient's magnitude ``g`` is a maximum across the edge (along the gradient's
    direction, in four directions, as Canny's non-maximum suppression): an edge's centre line. (A maximum over
    all eight neighbours keeps a sharp edge's corners and few points of a soft edge, whose ridge runs flat
    along it: a plate blurred by 3 pixels gave 10 points where it has hundreds.)"""
    angle = (np.degrees(np.arctan2(gy, gx)) + 180.0) % 180.0
    padded = np.pad(g, 1, mode="edge")
    h, w = g.shape

    def at(dy, dx):
        return padded[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]

    out = np.zeros(g.shape, bool)
    for lo, hi, (dy, dx) in ((-1, 22.5, (0, 1)), (157.5, 181, (0, 1)), (22.5, 67.5, (1, 1)), (67.5, 112.5, (1, 0)),
                             (112.5, 157.5, (1, -1))):
        sector = (angle >= lo) & (angle < hi)
        out |= sector & (g >= at(dy, dx)) & (g >= at(-dy, -dx))
    return out


def blurred_map(pixels: np.ndarray, sigma: float) -> np.ndarray:
    """The equirectangular map (H, W, 3) blurred by a Gaussian of ``sigma`` radians on the sphere:
    in latitude by sigma, in longitude by sigma over the cosine of latitude (in ``BANDS`` bands,
    wrapping around), at most a full turn; ``sigma`` under a quarter of a texel returns the map."""
    import cv2

    h, w = pixels.shape[:2]
    texel = math.pi / h
    sigma = min(float(sigma), MAX_BLUR)
    if sigma < 0.25 * texel:
        return pixels
    src = np.ascontiguousarray(pixels, dtype=np.float32)
    sv = sigma / texel
    pad = min(int(math.ceil(3 * sv)), h)
    out = cv2.GaussianBlur(np.pad(src, ((pad, pad), (0, 0), (0, 0)), mode="reflect"), (1, 2 * pad + 1), sigmaX=1e-6,
                           sigmaY=sv)[pad:pad + h]
    result = np.empty_like(out)
    edges = np.linspace(0, h, BANDS + 1).round().astype(int)
    for top, bottom in zip(edges[:-1], edges[1:]):
        if bottom <= top:
            continue
        latitude = (0.5 - (0.5 * (top + bottom)) / h) * math.pi
        sh = min(sv / max(math.cos(latitude), 1e-3), w / 2.0)
        pad = min(int(math.ceil(3 * sh)), w)
        band = np.pad(out[top:bottom], ((0, 0), (pad, pad), (0, 0)), mode="wrap")
        result[top:bottom] = cv2.GaussianBlur(band, (2 * pad + 1, 1), sigmaX=sh, sigmaY=1e-6)[:, pad:pad + w]
    return result
