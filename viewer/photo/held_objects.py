"""What the person holds or stands on (skis and poles, a bag, a bat): kept with the person where it
can be told from the background.

The pose model's segmentation is the person's body alone; a ski pole leaving the hand or a ski
under the boot is cut away with the background, and the relit person floats. An object is found
as what touches the person at a hand or a foot and stands out of the background around it, step
by step (docs/photos.md shows the skier before and after):

1. **The background's own statistics** (robust, so thin objects do not pull them): the per-channel
   median and median absolute deviation of the photo in windows of ``WINDOW`` of the person's
   height, the person itself filled from the background around it. A pixel's *contrast* is its
   largest per-channel deviation from that median in those deviations (a textured brick wall or
   crowd varies a lot, so only what is far outside its variation stands out).
2. **Parts that touch**: connected parts of the pixels of contrast above ``WEAK`` (gaps of a few
   pixels closed), within ``REACH`` of a hand or foot, that touch the person within ``SEED`` of a
   hand or foot landmark; then parts within ``GAP`` of those, for ``CHAINS`` rounds (a ski's white
   middle on white snow breaks it into pieces).
3. **Kept only if sure**: of those, a part is kept if it ends within the reach and the frame (a
   part that runs on to the reach's rim or out of the frame is background structure as far as can
   be told: a stair's edge, a kerb, a lamp post; an object the frame cuts is left out), is large
   enough (``MIN_AREA`` of the person) and stands out clearly (its 90th percentile of contrast at
   least ``SURE``: the edges of stairs and the contact shadow around a shoe stand out less). Of a
   kept part, the object is what stands out above ``CORE`` and the pixels beside it (its edge, mixed
   with the background): the weak pixels join the pieces, they are mostly the snow or the shadow
   around a ski.

What cannot be told from the background by colour (a dark barbell plate against dark bricks) is
left out, as before; a mask file that includes the object keeps it whatever it looks like
(:func:`viewer.photo.matting.mask_matte`). Everything runs where the person is ``SOLVE_HEIGHT``
pixels tall (0.03-0.3 s a photo on the evaluation set, docs/photos.md).
"""

from __future__ import annotations

import numpy as np

SOLVE_HEIGHT = 400  # objects are found where the person is this many pixels tall (or less)
WINDOW = 0.3  # of the person's height: the background's median and deviation are taken over this window
FLOOR = 0.02  # added to the background's deviation (colours in [0, 1]): a flat backdrop still has noise
WEAK = 3.0  # contrast (background deviations) above which a pixel may be part of an object
SURE = 8.0  # an object's 90th percentile of contrast is at least this
CORE = 6.0  # of a kept part, the pixels above this contrast and their neighbours are the object
REACH = 0.8  # of the person's height: objects lie within this distance of a hand or a foot
SEED = 0.15  # of the person's height: an object touches the person this near a hand or a foot landmark
GAP = 0.04  # of the person's height: pieces of one object this far apart are joined
CHAINS = 4  # joining rounds
MIN_AREA = 0.0015  # of the person's area: smaller parts are not kept
TOUCH = 3  # pixels: a part this near the person touches it
CLOSE = 5  # pixels: the weak pixels' gaps closed by this square
HANDS = (15, 16, 17, 18, 19, 20, 21, 22)  # MediaPipe's wrist and hand landmarks
FEET = (27, 28, 29, 30, 31, 32)  # ankles, heels and toes
MAD_SCALE = 1.4826  # the median absolute deviation of a normal distribution, in its standard deviations


def _median(image: np.ndarray, size: int) -> np.ndarray:
    """Per-channel median filter of ``image`` (H, W, 3) in [0, 1] over ``size`` x ``size``
    (OpenCV's, on 8-bit values: its large kernels take 8 bits only)."""
    import cv2

    out = [cv2.medianBlur(np.round(np.clip(image[..., c], 0.0, 1.0) * 255).astype(np.uint8), size) for c in range(3)]
    return np.stack(out, axis=-1).astype(np.float32) / 255.0


def contrast(image: np.ndarray, person: np.ndarray, height: int) -> np.ndarray:
    """(H, W): each pixel's largest per-channel deviation from the background's median around
    it, in the background's median absolute deviations (``image`` float RGB in [0, 1])."""
    import cv2

    from viewer.photo.detail import masked_lowpass

    near = cv2.dilate(person.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    filled = np.where(near[..., None], masked_lowpass(image, (~near).astype(np.float32), 0.05 * height), image)
    size = min(2 * int(WINDOW * height / 2) + 1, 255)  # odd; OpenCV's 8-bit median takes any odd size
    median = _median(filled, size)
    deviation = image - median
    spread = _median(np.abs(deviation), size)
    return (np.abs(deviation) / (MAD_SCALE * spread + FLOOR)).max(axis=-1)


def _discs(points: list, radius: int, shape: tuple[int, int]) -> np.ndarray:
    import cv2

    out = np.zeros(shape, np.uint8)
    for x, y in points:
        cv2.circle(out, (int(round(x)), int(round(y))), max(radius, 1), 1, -1)
    return out > 0


def find_objects(image: np.ndarray, person: np.ndarray, landmarks: dict, height: int) -> np.ndarray:
    """(H, W) bool: the objects touching ``person`` (bool) at its hands and feet, at ``image``'s
    size (float RGB in [0, 1]); ``landmarks`` MediaPipe's index -> normalized (x, y); ``height``
    the person's, pixels."""
    import cv2

    h, w = person.shape
    points = [(x * w, y * h) for i, (x, y) in landmarks.items() if i in HANDS + FEET]
    if not points or not person.any():
        return np.zeros((h, w), bool)
    reach = _discs(points, int(REACH * height), (h, w))
    z = contrast(image, person, height)
    weak = (z > WEAK) & reach & ~person
    weak = cv2.morphologyEx(weak.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((CLOSE, CLOSE), np.uint8)) > 0
    weak &= ~person
    count, labels = cv2.connectedComponents(weak.astype(np.uint8), connectivity=8)
    if count <= 1:
        return np.zeros((h, w), bool)
    grown_person = cv2.dilate(person.astype(np.uint8), np.ones((2 * TOUCH + 1,) * 2, np.uint8)) > 0
    contact = _discs(points, int(SEED * height), (h, w)) & grown_person & weak
    keep = np.zeros(count, bool)
    keep[np.unique(labels[contact])] = True
    joint = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * max(1, int(GAP * height)) + 1,) * 2)
    for _ in range(CHAINS):  # pieces of one object, found one from the other
        keep[0] = False
        near = cv2.dilate(keep[labels].astype(np.uint8), joint) > 0
        before = keep.copy()
        keep[np.unique(labels[near & weak])] = True
        if (keep == before).all():
            break
    keep[0] = False
    rim = reach & ~(cv2.erode(reach.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0)
    rim[[0, -1], :] = rim[:, [0, -1]] = True  # the frame's edge too: what the frame cuts cannot be seen to end
    keep[np.unique(labels[rim & weak])] = False  # runs on: the background's (a stair's edge, a kerb, a lamp post)
    area = np.bincount(labels.ravel(), minlength=count)
    for i in np.flatnonzero(keep):
        keep[i] = area[i] >= MIN_AREA * person.sum() and np.percentile(z[labels == i], 90) >= SURE
    keep[0] = False
    found = keep[labels]
    core = (found & (z > CORE)).astype(np.uint8)  # the weak pixels joined the parts; the object is their clear core
    return found & (cv2.dilate(core, np.ones((3, 3), np.uint8)) > 0)


def held_objects(photo: np.ndarray, person: np.ndarray, landmarks: dict, height: int) -> np.ndarray:
    """(H, W) bool at ``photo``'s size (uint8 sRGB): :func:`find_objects`, run where the person
    (``person`` bool, ``height`` pixels tall) is ``SOLVE_HEIGHT`` pixels tall or less."""
    from viewer.resize import height_capped, resize

    h, w = person.shape
    size = height_capped((w, h), height, SOLVE_HEIGHT)
    small = resize(person.astype(np.float32), size) > 0.5
    found = find_objects(resize(photo, size).astype(np.float32) / 255.0, small, landmarks,
                         max(1, int(round(height * size[0] / w))))
    return found if size == (w, h) else resize(found.astype(np.float32), (w, h)) > 0.5
