"""What of the plate stands in front of the person, as the user marks it: ``--front MASK.png``.

The plate's own people nearer the camera are found and matted by themselves
(:func:`viewer.plate.people.in_front`); an object is not (a barbell held over the person, a
post, a table): no model this product ships segments arbitrary objects. The user paints what stands
in front, white on black (or opaque on transparent), at the plate's shape, in any image editor.

- **Read** as a mask is (:func:`viewer.photo.frames.read_image_u8`: values, not colours): its
  alpha where it has one that is not wholly opaque, else its grey level; brought to the plate's size.
  A mask of another shape than the plate (its aspect off by more than ``ASPECT_SLACK``), a mask that
  marks nothing or the whole plate is one line naming the file.
- **A hard mask follows the plate's edges.** A mask of two values (a brush without softness, a
  polygon) is a hand's outline: its edge, within ``EDGE`` of the plate's longer side of it, is
  refined by OpenCV's guided filter (He et al. 2013, ``cv2.ximgproc.guidedFilter``, the plate as its
  guide) so that it hugs the object's own outline and blends over a pixel or two as a photo's edges
  do; inside and outside that band the mask is kept. A soft mask (a matte from a compositor) is taken
  as given. (A mask of two values is taken as that: a red stroke on black, a grey one, mark alike.)

The composite hides the person, and their shadow, where the mask is
(:func:`viewer.output.plate_composite.composite_on_plate`), in the command, a clip on the plate and the
window alike (the mask rides on the :class:`viewer.plate.loader.Plate`).
"""

from __future__ import annotations

import numpy as np

from viewer.errors import InputError
from viewer.resize import resize

ASPECT_SLACK = 0.01  # the mask's aspect may differ from the plate's by this share (a pixel's rounding)
EDGE = 0.004  # of the plate's longer side: the band about a hard mask's edge the guided filter refines
GUIDE_EPS = 1e-3  # the guided filter's regularization (colours in [0, 1]): edges of 0.03 and more are followed
LEAST = 1e-4  # of the plate: a mask marking less than this marks nothing
MOST = 0.99  # of the plate: a mask marking more than this hides everything


def read_front(path, srgb: np.ndarray, notes: list) -> np.ndarray:
    """(H, W) float32 in [0, 1] at the size of the plate ``srgb`` (H, W, 3 uint8): the mask at ``path``
    as the module says; one line naming the file when it cannot be used."""

    from viewer.photo.frames import read_image_u8

    image = read_image_u8(path, "front mask", notes, colours=False)
    h, w = srgb.shape[:2]
    if image.ndim == 3 and image.shape[-1] in (2, 4) and int(image[..., -1].min()) < 255:
        values = image[..., -1]  # its alpha: opaque where something stands in front
    elif image.ndim == 3:
        values = image[..., :3].max(axis=-1) if image.shape[-1] >= 3 else image[..., 0]  # (a red stroke marks too)
    else:
        values = image
    mh, mw = values.shape[:2]
    if abs((mw / mh) / (w / h) - 1.0) > ASPECT_SLACK:
        raise InputError(path, f"is {mw}x{mh}, the plate {w}x{h}: a front mask is the plate's shape (white where something "
                               "stands in front of the person)")
    levels = np.flatnonzero(np.bincount(values.ravel(), minlength=256))
    hard = len(levels) == 2  # two values (a brush without softness, a polygon): the lower nothing, the higher in front
    mask = ((values >= levels[1]) if hard else values / 255.0).astype(np.float32)
    if (mw, mh) != (w, h):
        mask = resize(mask, (w, h), "area" if mw > w else "linear")
    share = float((mask > 0.5).mean())
    if share < LEAST:
        raise InputError(path, "marks nothing (a front mask is white where something of the plate stands in front of the person)")
    if share > MOST:
        raise InputError(path, f"marks {100 * share:.0f} % of the plate: the person would be hidden wherever they stand; "
                               "mark only what stands in front of them")
    if hard:
        mask = _along_edges(mask, srgb)
        notes.append(f"the front mask's edge follows the plate's edges (guided filter over {_band(srgb.shape):d} px)")
    return np.clip(mask, 0.0, 1.0).astype(np.float32)


def _band(shape) -> int:
    return max(int(round(EDGE * max(shape[:2]))), 2)


def _along_edges(mask: np.ndarray, srgb: np.ndarray) -> np.ndarray:
    """A hard ``mask`` refined within :data:`EDGE` of its edge by the guided filter on the plate (worked over the
    mask's bounding box and the band: a small object on a 12-MP plate costs its box, not the plate)."""
    import cv2

    radius = _band(srgb.shape)
    hard = (mask > 0.5).astype(np.uint8)
    rows, cols = np.flatnonzero(hard.any(axis=1)), np.flatnonzero(hard.any(axis=0))
    y0, y1 = max(rows[0] - 3 * radius, 0), min(rows[-1] + 3 * radius + 1, mask.shape[0])
    x0, x1 = max(cols[0] - 3 * radius, 0), min(cols[-1] + 3 * radius + 1, mask.shape[1])
    box = hard[y0:y1, x0:x1]
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    band = cv2.dilate(box, kernel) > cv2.erode(box, kernel)
    # the guide in 8 bits, its regularization in those units (a float guide is taken as no guide by this build:
    # the filter then only blurs, and a thin pole on a 12-MP plate came out a third opaque)
    guide = np.ascontiguousarray(srgb[y0:y1, x0:x1])
    soft = cv2.ximgproc.guidedFilter(guide, box.astype(np.float32), radius, GUIDE_EPS * 255.0 ** 2)
    out = hard.astype(np.float32)
    out[y0:y1, x0:x1] = np.where(band, np.clip(soft, 0.0, 1.0), box)
    return out
