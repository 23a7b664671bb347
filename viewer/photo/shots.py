"""Where a clip's shots cut: what is estimated once per shot (the photo's own lighting, the exposure)
is estimated again after a cut.

A cut is a frame whose colours, as a whole, are not the frame before's: the Bhattacharyya distance
between the two frames' hue-saturation histograms (OpenCV's ``compareHist``, on frames shrunk to
``SIDE`` pixels) above ``CUT``. The content detector of PySceneDetect works the same way on HSV;
a person moving, a camera panning and a light flickering move the histogram far less than a cut.
"""

from __future__ import annotations

import numpy as np

from viewer.resize import resize

SIDE = 96  # pixels of the shrunk frame's longer side
BINS = (24, 8)  # hue, saturation
CUT = 0.45  # Bhattacharyya distance between consecutive frames beyond which a new shot starts


def histogram(rgb: np.ndarray) -> np.ndarray:
    """The frame's normalized hue-saturation histogram."""
    import cv2

    h, w = rgb.shape[:2]
    scale = SIDE / max(h, w)
    small = resize(rgb, (max(int(w * scale), 1), max(int(h * scale), 1)), "area")
    hsv = cv2.cvtColor(small, cv2.COLOR_RGB2HSV)
    hist = cv2.calcHist([hsv], [0, 1], None, list(BINS), [0, 180, 0, 256])
    return cv2.normalize(hist, None, 1.0, 0.0, cv2.NORM_L1)


class ShotCuts:
    """Fed the frames in order (:meth:`shot_of`), says the shot each is in (0, 1, ...)."""

    def __init__(self):
        self.shot = 0
        self._previous = None

    def shot_of(self, rgb: np.ndarray | None) -> int:
        """The shot of the next frame (``rgb`` None: a lost frame, in the shot before it)."""
        import cv2

        if rgb is None:
            return self.shot
        hist = histogram(rgb)
        if self._previous is not None and cv2.compareHist(self._previous, hist, cv2.HISTCMP_BHATTACHARYYA) > CUT:
            self.shot += 1
        self._previous = hist
        return self.shot
