"""A clip's face landmarks smoothed from frame to frame: the One Euro filter (Casiez, Roussel and
Vogel, CHI 2012), the filter MediaPipe's own landmark smoothing uses.

The face landmark model sees every frame afresh: on a still face its 468 points wander by a few
tenths of a pixel to a pixel from frame to frame, and the face's surface (its normals, blended into
the person's, :mod:`viewer.photo.face`) wobbles with them: relit, the cheeks shimmer. The One Euro
filter is an exponential filter whose cut-off rises with the speed: a still face is smoothed hard
(little jitter), a face that turns or moves is followed with little lag. Units here are per frame
and, for the speed, per face width, so the same settings hold for a small face and a close-up; at
25-30 frames a second ``MIN_CUTOFF`` is ~1.5 Hz.

Only the person's largest face is followed (the one the relighting uses); the filter starts afresh at
a cut (a new shot), after a frame without a face, and when the face found is not the one before
(its centre moved more than ``JUMP`` face widths, or its width changed by more than ``RESIZE`` times).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

MIN_CUTOFF = 0.05  # cycles per frame: the cut-off of a still face (strong smoothing)
BETA = 8.0  # the cut-off's rise per face width a frame of speed (a turning head is followed)
D_CUTOFF = 0.5  # cycles per frame: the cut-off of the speed's own estimate
JUMP = 0.5  # face widths: a face whose centre moved more than this is another face
RESIZE = 1.5  # ... or whose width changed more than this many times


def _alpha(cutoff: np.ndarray | float) -> np.ndarray | float:
    """The exponential filter's weight of the new sample for a cut-off in cycles per frame (dt = 1)."""
    tau = 1.0 / (2.0 * math.pi * np.asarray(cutoff))
    return 1.0 / (1.0 + tau)


class OneEuro:
    """The One Euro filter over an array of values (each element filtered on its own), one sample a frame."""

    def __init__(self, min_cutoff: float = MIN_CUTOFF, beta: float = BETA, d_cutoff: float = D_CUTOFF):
        self.min_cutoff, self.beta, self.d_cutoff = min_cutoff, beta, d_cutoff
        self.value: np.ndarray | None = None
        self.speed: np.ndarray | None = None

    def reset(self) -> None:
        self.value = self.speed = None

    def __call__(self, x: np.ndarray, scale: float = 1.0) -> np.ndarray:
        """The filtered value of sample ``x``; ``scale``: the unit speeds are measured in (a face's width)."""
        x = np.asarray(x, np.float64)
        if self.value is None:
            self.value, self.speed = x.copy(), np.zeros_like(x)
            return x.copy()
        a_d = _alpha(self.d_cutoff)
        self.speed = a_d * (x - self.value) + (1.0 - a_d) * self.speed
        a = _alpha(self.min_cutoff + self.beta * np.abs(self.speed) / scale)
        self.value = a * x + (1.0 - a) * self.value
        return self.value.copy()


class FaceTrack:
    """Fed a clip's faces frame by frame (:meth:`smooth`), returns them with the largest one's
    landmarks filtered."""

    def __init__(self):
        self.filter = OneEuro()
        self._last = None  # (centre x, y, width) of the face followed

    def restart(self) -> None:
        self.filter.reset()
        self._last = None

    def smooth(self, faces: list) -> list:
        """``faces`` (:class:`viewer.photo.face.FaceLandmarks`, largest first) with the first one's
        points filtered; none: the filter starts afresh at the next face."""
        if not faces:
            self.restart()
            return faces
        face = faces[0]
        width = max(face.width, 1.0)
        centre = face.points[:, :2].mean(axis=0)
        if self._last is not None:
            moved = float(np.hypot(*(centre - self._last[:2]))) / width
            grown = max(width / self._last[2], self._last[2] / width)
            if moved > JUMP or grown > RESIZE:
                self.filter.reset()
        self._last = np.array([centre[0], centre[1], width])
        points = self.filter(face.points, scale=width)  # speeds per face width: one setting for every face size
        return [replace(face, points=points), *faces[1:]]
