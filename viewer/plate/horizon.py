"""Where the plate's horizon is: the camera's tilt read from its vertical lines.

A level camera sees vertical edges (walls, poles, doorways) parallel, and its horizon through the
middle of the picture. Tilted up by theta, the verticals converge to a point above the picture, at
``f / tan(theta)`` from its centre, and the horizon drops to ``f tan(theta)`` below it (``f`` the focal
length in pixels). The near-vertical segments of OpenCV's line segment detector (von Gioi et al.
2012; within ``MAX_LEAN`` of vertical, at least ``MIN_LENGTH`` of the plate's height) vote for that
point (the least-squares meeting point of their lines, weighted by length, in homogeneous
coordinates so parallel lines meet at infinity: a level camera; twice the segments that miss it most,
``TRIM``, are left out and it is found again). The plate's people's edges do not vote (a limb leans as
the person stands: the bench's plates of people standing on a level camera's ground read tilts of up to
34 degrees from them). Fewer than ``MIN_SEGMENTS``
(a landscape with no verticals): the level camera's middle, said so.
"""

from __future__ import annotations

import math

import numpy as np

from viewer.plate.loader import Plate

MAX_LEAN = 15.0  # degrees from vertical: a segment leaning more is not a vertical edge
MIN_LENGTH = 0.04  # of the plate's height
MIN_SEGMENTS = 8
MAX_TILT = 35.0  # degrees: a tilt read beyond this is not believed (the level camera's middle instead)
SIDE = 1024  # pixels: the plate's longer side the segments are found at
AWAY_GROW = 0.005  # of the plate's height: the people's segmentation grown by this before their edges are left out
TRIM, TRIM_ROUNDS = 0.3, 2  # each round, the share of segments that miss the meeting point most is left out


def plate_horizon(plate: Plate) -> tuple[float, str]:
    """(the horizon's height as a fraction of the plate's, from its top; how it was found). The edges of the
    plate's people (:attr:`Plate.people`: their limbs lean as they stand, not as the world's verticals do) do
    not vote."""
    import cv2

    h = plate.size[1]
    people = [p.segmentation > 0.3 for p in plate.people]
    away = None
    if people:  # grown a little: a limb's edge lies on the outline, a segment along it just outside
        grow = max(int(round(AWAY_GROW * h)), 1)
        away = cv2.dilate(np.any(people, axis=0).astype(np.uint8), np.ones((2 * grow + 1, 2 * grow + 1), np.uint8)) > 0
    below, how = vertical_horizon(plate.srgb, plate.focal_px, away)
    return (0.5, how) if below is None else (float(np.clip(0.5 + below * plate.focal_px / h, 0.0, 1.0)), how)


def horizon_tilt(horizon: float, height: float, focal_px: float) -> float:
    """The camera's upward tilt in radians (down: negative) whose horizon lies ``horizon`` of a picture
    ``height`` pixels high from its top, through a lens of ``focal_px`` (the inverse of :func:`plate_horizon`'s
    row): the horizon below the middle, the camera tilted up."""
    return math.atan((horizon - 0.5) * height / focal_px)


def vertical_horizon(srgb: np.ndarray, focal_px: float, away: np.ndarray | None = None) -> tuple[float | None, str]:
    """(how far below the middle of ``srgb`` (H, W, 3) uint8 the horizon is, in focal lengths (the
    tangent of the camera's upward tilt; None: a level camera assumed), how it was found) from its
    vertical edges (module docstring); ``focal_px``: the focal length in ``srgb``'s pixels; ``away``
    (H, W) bool: where edges are not the scene's (a person's limbs)."""
    import cv2

    from viewer.resize import resize, scaled_size

    h, w = srgb.shape[:2]
    grey = cv2.cvtColor(srgb, cv2.COLOR_RGB2GRAY)
    if max(w, h) > SIDE:
        grey = resize(grey, scaled_size((w, h), SIDE))
    sh, sw = grey.shape
    scale = sw / w
    focal = focal_px * scale
    found = cv2.createLineSegmentDetector().detect(grey)[0]
    if found is None:
        return None, "no lines: a level camera assumed"
    x1, y1, x2, y2 = (found.reshape(-1, 4).astype(np.float64)).T
    length = np.hypot(x2 - x1, y2 - y1)
    lean = np.degrees(np.arctan2(np.abs(x2 - x1), np.abs(y2 - y1)))
    keep = (lean <= MAX_LEAN) & (length >= MIN_LENGTH * sh)
    if away is not None:  # a segment whose middle lies on what is not the scene does not vote
        mx = np.clip(((x1 + x2) / 2 / scale).astype(int), 0, w - 1)
        my = np.clip(((y1 + y2) / 2 / scale).astype(int), 0, h - 1)
        keep &= ~away[my, mx]
    if keep.sum() < MIN_SEGMENTS:
        return None, f"{int(keep.sum())} vertical edges: a level camera assumed"
    cx, cy = 0.5 * sw, 0.5 * sh
    a = np.stack([(x1[keep] - cx) / focal, (y1[keep] - cy) / focal, np.ones(int(keep.sum()))], axis=1)
    b = np.stack([(x2[keep] - cx) / focal, (y2[keep] - cy) / focal, np.ones(int(keep.sum()))], axis=1)
    lines = np.cross(a, b)
    lines /= np.linalg.norm(lines[:, :2], axis=1, keepdims=True)
    weight = length[keep]
    for _ in range(TRIM_ROUNDS):  # the segments that miss the meeting point most are not verticals (a sign's edge, a tree)
        _, _, vt = np.linalg.svd(lines * weight[:, None])
        miss = np.abs(lines @ vt[-1]) / max(float(np.linalg.norm(vt[-1][:2])) + abs(float(vt[-1][2])), 1e-12)
        weight = np.where(miss <= np.percentile(miss, 100 * (1 - TRIM)), length[keep], 0.0)
    _, _, vt = np.linalg.svd(lines * weight[:, None])
    u, v, w_ = vt[-1]
    if abs(v) < 1e-12:
        return None, "the vertical edges lean sideways only: a level camera assumed"
    horizon = -w_ / v  # normalized: the vertical vanishing point at v / w below the centre puts the horizon at -w / v
    tilt = math.degrees(math.atan(horizon))
    if abs(tilt) > MAX_TILT:
        return None, f"a tilt of {tilt:.0f} degrees read from the vertical edges is not believed: a level camera assumed"
    return float(horizon), (f"from {int(keep.sum())} vertical edges: the camera tilted {abs(tilt):.1f} degrees "
                            f"{'up' if tilt > 0 else 'down'}")
