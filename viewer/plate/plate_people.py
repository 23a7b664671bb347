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

from viewer.plate.plate_file import Plate

MIN_TALL = 0.05  # of the plate's height: people smaller are too few pixels to measure
MIN_ASPECT = 1.8  # a standing person's height over their width at least
EDGE = 0.005  # of the plate's height: a segmentation this near the top or bottom edge is cut by it
CAMERA_RANGE = (0.2, 30.0)  # metres: heights outside are not a camera standing on this ground
ANKLES, HIPS, SHOULDERS, FEET = (27, 28), (23, 24), (11, 12), (29, 30, 31, 32)


def standing_heights(plate: Plate, horizon: float, person_m: float) -> list[float]:
    """The camera height (metres) each whole standing person in ``plate`` gives, on ``horizon`` (a
    fraction of its height), each taken as ``person_m`` tall."""
    from viewer.photo.segmentation import find_people

    heights = []
    for person in find_people(plate.srgb, plate.source):
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
