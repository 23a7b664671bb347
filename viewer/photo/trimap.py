"""The matte's trimap: the person for sure, the background for sure and the band between, from the
segmentation and the pose (:func:`trimap`), and what a clip's frame before carries to it (:class:`Carried`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewer.photo.pose_masks import bones_mask, gaps_mask, head_mask, person_height

CORE = 0.02  # of the person's height: deeper than this inside the segmentation is the person for sure
OUTER = 0.012  # of the person's height: farther than this outside it is the background for sure
BONE = 0.01  # the pose's bones, drawn this thick (of the person's height), are sampled for the person's colours


@dataclass(frozen=True)
class Carried:
    """A clip's frame before, brought to this frame along the optical flow (:meth:`viewer.photo.steady.SteadyMaps.carried_matte`):
    its matte ``alpha`` (H, W) in [0, 1] and where the flow holds, ``held`` (H, W) in [0, 1]
    (:func:`viewer.photo.steady.smooth_weight`; :func:`decided_outline` counts only where it is all but 1)."""

    alpha: np.ndarray
    held: np.ndarray
    objects: np.ndarray | None = None  # (H, W) bool: what the frame before was found holding (confirmed or not), carried here


def distances(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distance inside, distance outside) of every pixel to the mask's outline, pixels."""
    import cv2

    m = mask.astype(np.uint8)
    return cv2.distanceTransform(m, cv2.DIST_L2, 5), cv2.distanceTransform(1 - m, cv2.DIST_L2, 5)


@dataclass(frozen=True)
class Trimap:
    """The segmentation's trimap (H, W) bool each: the person for sure, the pixels its colours are
    sampled from (the sure person and its bones), the background for sure; the band is the rest.
    ``inside``, ``outside``: each pixel's distance to the segmentation's outline; ``height`` the
    person's, pixels."""

    sure_person: np.ndarray
    samples: np.ndarray
    sure_background: np.ndarray
    inside: np.ndarray
    outside: np.ndarray
    height: int

    @property
    def band(self) -> np.ndarray:
        return ~self.sure_person & ~self.sure_background


def trimap(segmentation: np.ndarray, landmarks: dict) -> Trimap:
    """The trimap of a soft segmentation (H, W) and the pose's landmarks (index -> normalized (x, y))."""
    h, w = segmentation.shape
    seg = segmentation > 0.5
    height = person_height(seg)
    inside, outside = distances(seg)
    sure_person = (inside > CORE * height) & ~gaps_mask(landmarks, (w, h))
    head = head_mask(landmarks, (w, h))
    if head is not None:  # the head within the segmentation: its hair kept against a background of its colour
        sure_person |= head & seg
    # the person's colours also come from its bones (a thin limb has no deep pixels)
    samples = sure_person | (bones_mask(landmarks, (w, h), int(round(BONE * height))) & seg)
    return Trimap(sure_person, samples, outside > OUTER * height, inside, outside, height)
