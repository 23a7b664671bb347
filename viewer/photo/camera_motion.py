"""How the camera turned during a shot, read from the old background's motion: the new background
(and the light, which is the same world seen from the turned camera) turns with it.

Between consecutive frames, the backward optical flow (:mod:`viewer.photo.flow`, DIS on the frame
shrunk to ``SIDE`` pixels) is taken where it holds and away from the person (their matte, grown by
``MARGIN`` of the frame, in either frame); its median over that background is how far the
background's content moved, in pixels: a camera that pans or tilts by a small angle moves the whole
background by the focal length times it, and a tripod's wobble by a fraction of a pixel. Each
frame is measured against a key frame (the shot's first, until the view has moved on), so the moves
do not add up errors frame by frame; a cut starts at 0. Too little background seen
(``MIN_SHARE`` of the frame) is taken as a camera that did not move. The median ignores a minority
that moves on its own (a passer-by); roll and zoom are not estimated.
"""

from __future__ import annotations

import numpy as np

from viewer.photo.flow import backward_flow, dis_flow, shrunk_grey, warp
from viewer.resize import resize

SIDE = 640  # pixels of the shrunk frame's longer side (0.4 px moves of a fine texture read 20 % long at 320 px, 13 % at full size)
MARGIN = 0.03  # of the frame's longer side: the person's matte grown by this is not background
MIN_SHARE = 0.05  # of the frame: less background than this, and the camera is taken as still
KEY_MOVE = 0.08  # of the frame's longer side: a view moved this far from its key frame becomes the key


class CameraMotion:
    """Fed a clip's frames in order (:meth:`shift_of`), says how far the background has moved since
    the shot's first frame. Each frame is compared with a key frame (the shot's first, until the
    view has moved ``KEY_MOVE`` of the frame from it or too little of its background is still seen),
    not only with the frame before: frame-to-frame moves of a slow drift are a fraction of a pixel,
    which the flow reads short, and added up they lost a third of a tripod's 6-pixel drift over
    two seconds (hybrik's tai chi clip)."""

    def __init__(self):
        self.flow = dis_flow()
        self.shot = None
        self.shift = np.zeros(2)
        self._previous = None  # (grey, not background, shift) of the frame before, at the shrunk size
        self._key = None  # the same of the key frame

    def _moved(self, small, person, other) -> np.ndarray | None:
        """The median backward flow from ``small`` to ``other``'s frame over the background both see
        (shrunk pixels), or None when too little is seen."""
        if other is None or other[0].shape != small.shape:
            return None
        back, held = backward_flow(self.flow, small, other[0])
        background = held & ~person & ~(warp(other[1].astype(np.float32), back) > 0.5)
        if background.sum() < MIN_SHARE * background.size:
            return None
        return np.median(back[background], axis=0)

    def shift_of(self, rgb: np.ndarray | None, alpha: np.ndarray | None, shot: int) -> tuple[float, float]:
        """(x, y): pixels of ``rgb``'s size the background's content has moved since the shot's first
        frame (a camera turning right moves it left: x < 0). ``alpha``: the person's matte at the same
        size (None: no person in the frame); ``rgb`` None: a lost frame (no move counted)."""
        if shot != self.shot:
            self.shot, self.shift, self._previous, self._key = shot, np.zeros(2), None, None
        if rgb is None:
            return float(self.shift[0]), float(self.shift[1])
        import cv2

        small, scale = shrunk_grey(rgb, SIDE)
        size = small.shape[::-1]
        person = np.zeros(small.shape, bool) if alpha is None else resize(alpha.astype(np.float32), size) > 0.02
        grow = max(int(round(MARGIN * max(size))), 1)
        person = cv2.dilate(person.astype(np.uint8), np.ones((2 * grow + 1, 2 * grow + 1), np.uint8)) > 0
        from_key = self._moved(small, person, self._key)
        if from_key is not None:
            self.shift = self._key[2] - from_key / scale
        else:
            from_previous = self._moved(small, person, self._previous)
            if from_previous is not None:
                self.shift = self._previous[2] - from_previous / scale
        here = (small, person, self.shift.copy())
        if self._key is None or from_key is None or np.abs(from_key).max() > KEY_MOVE * max(size):
            self._key = here
        self._previous = here
        return float(self.shift[0]), float(self.shift[1])


def turned(shift: tuple[float, float], focal_px: float) -> tuple[float, float]:
    """(yaw, tilt) in degrees that move a view's content by ``shift`` pixels (``focal_px``: the
    focal length in those pixels): the look's turn that makes the new background follow the old.
    Linear, not an arctangent: a pan is a sum of small steps, each the focal length times its angle."""
    return -float(np.degrees(shift[0] / focal_px)), -float(np.degrees(shift[1] / focal_px))
