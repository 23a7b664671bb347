"""The plate camera's height above the ground, from the people standing in the plate.

A person of ``H`` metres (``viewer.plate.placement.PERSON_HEIGHT_M``, which the caller gives)
standing with their feet ``d`` below the horizon and ``T`` tall in the picture (both fractions of
its height) is seen from ``H * d / T`` metres above the
ground, whatever the lens or their distance (:mod:`viewer.plate.placement`, where the default size
assumes a camera at eye height). The people are MediaPipe's (:func:`viewer.photo.segmentation.find_people`);
one counts when they stand whole in the plate: their ankles, hips and shoulders seen, in that order
from the bottom, their segmentation clear of the plate's top and bottom edges, at least
``MIN_TALL`` of the plate tall and taller than ``MIN_ASPECT`` times their width, their feet below
the horizon. Their top is their segmentation's, their feet the lowest of their heels and toes. The
median over them is the camera's height (people differ by +-10 % in height; a child or someone
sitting counts as a short adult: more people, a better median).
"""

from __future__ import annotations

import numpy as np

from viewer.plate.loader import Plate

MIN_TALL = 0.05  # of the plate's height: people smaller are too few pixels to measure
MIN_ASPECT = 1.8  # a standing person's height over their width at least
EDGE = 0.005  # of the plate's height: a segmentation this near the top or bottom edge is cut by it
CAMERA_RANGE = (0.2, 30.0)  # metres: heights outside are not a camera standing on this ground
ANKLES, HIPS, SHOULDERS, FEET = (27, 28), (23, 24), (11, 12), (29, 30, 31, 32)


def standing_heights(plate: Plate, horizon: float, person_m: float) -> list[float]:
    """The camera height (metres) each whole standing person in ``plate`` gives, on ``horizon`` (a
    fraction of its height), each taken as ``person_m`` tall."""
    heights = []
    for person in plate.people:
        lm = person.landmarks
        if not all(i in lm for i in (*ANKLES, *HIPS, *SHOULDERS)):
            continue
        y = {k: float(np.mean([lm[i][1] for i in idx])) for k, idx in (("ankle", ANKLES), ("hip", HIPS), ("shoulder", SHOULDERS))}
        if not y["shoulder"] < y["hip"] < y["ankle"]:
            continue  # lying, bent over, upside down
        rows = np.flatnonzero((person.segmentation > 0.5).any(axis=1))
        cols = np.flatnonzero((person.segmentation > 0.5).any(axis=0))
        if not len(rows):
            continue
        h = person.segmentation.shape[0]
        top = rows[0] / h
        feet = max([lm[i][1] for i in FEET if i in lm] + [y["ankle"]])
        tall, wide = feet - top, (cols[-1] + 1 - cols[0]) / h
        if top <= EDGE or (rows[-1] + 1) / h >= 1.0 - EDGE or tall < MIN_TALL or tall < MIN_ASPECT * wide or feet <= horizon:
            continue
        camera = person_m * (feet - horizon) / tall
        if CAMERA_RANGE[0] <= camera <= CAMERA_RANGE[1]:
            heights.append(float(camera))
    return heights


def plate_camera_height(plate: Plate, horizon: float, person_m: float) -> tuple[float | None, int]:
    """(the plate camera's height in metres from the people standing in it, each ``person_m`` tall, or
    None without any; how many)."""
    heights = standing_heights(plate, horizon, person_m)
    return (float(np.median(heights)) if heights else None), len(heights)


NEARER = 0.01  # of the plate's height: a person of the plate whose feet are this much lower stands in front


def feet_row(person) -> float:
    """Where a person of the plate stands (a fraction of its height): the lowest of their heels, toes and
    ankles seen, else their segmentation's bottom."""
    seen = [person.landmarks[i][1] for i in (*FEET, *ANKLES) if i in person.landmarks]
    if seen:
        return float(max(seen))
    rows = np.flatnonzero((person.segmentation > 0.5).any(axis=1))
    return float((rows[-1] + 1) / person.segmentation.shape[0]) if len(rows) else 0.0


def in_front(plate: Plate, feet: float, box: tuple[float, float, float, float], mattes: dict | None = None) -> np.ndarray | None:
    """(H, W) float32 at the plate's size: the matte of the plate's people who stand nearer the camera
    than feet at ``feet`` (a fraction of its height) and overlap ``box`` (x0, y0, x1, y1, the plate's
    pixels): they hide the person put behind them. Their mattes are the photo pipeline's
    (:func:`viewer.photo.matting.automatic_matte`: the colour cut and the closed-form edge; kept in
    ``mattes`` by the person's index when given, for the next placement), and what the user marked as standing
    in front (the plate's ``front``, :mod:`viewer.plate.front_mask`); None when nothing stands in front."""
    from viewer.photo.matting import automatic_matte

    out = None
    mattes = {} if mattes is None else mattes
    for k, person in enumerate(plate.people):
        if feet_row(person) < feet + NEARER:
            continue
        rows = np.flatnonzero((person.segmentation > 0.5).any(axis=1))
        cols = np.flatnonzero((person.segmentation > 0.5).any(axis=0))
        if not len(rows) or cols[-1] + 1 <= box[0] or cols[0] >= box[2] or rows[-1] + 1 <= box[1] or rows[0] >= box[3]:
            continue
        if k not in mattes:
            mattes[k] = automatic_matte(plate.srgb, person).alpha
        out = mattes[k] if out is None else np.maximum(out, mattes[k])
    if plate.front is not None:
        out = plate.front if out is None else np.maximum(out, plate.front)
    return None if out is None else out.astype(np.float32)

