"""The relit person composited into a plate, in the plate's linear light, blurred as the plate is where they stand.

    composite = plate x shadow x (1 - alpha) + person

``person`` is the relit person premultiplied by its matte (the engine's ``read_hdr_rgba``), ``shadow``
the ground's light left by the person (1 minus the share the ground shadow pass says the person
takes away: a shadow catcher), both brought from the person's frame into the plate by the
placement's scale and offset (:mod:`viewer.plate.placement`): shrunk by area first where the person
gets smaller (no aliasing at the hair), then moved by bilinear interpolation to the sub-pixel
offset. The plate's own pixels are untouched outside the person and their shadow, so the plate
comes back as it was (sRGB in, linear, sRGB out: the same 8 bits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewer.plate.placement import PlateTransform
from viewer.resize import resize

MAX_HALF = 65504.0  # the largest value a half-float EXR holds: a highlight brighter is clipped there


@dataclass(frozen=True)
class PlateComposite:
    """The composite (H, W, 3) linear, and its layers for compositors at the plate's size: the person
    premultiplied with its matte (H, W, 4), the shadow as a multiplier of the plate (H, W, 3)."""

    image: np.ndarray
    person: np.ndarray
    shadow: np.ndarray


def into_plate(image: np.ndarray, transform: PlateTransform, plate_size: tuple[int, int]) -> np.ndarray:
    """``image`` (h, w, C) float32 of the person's frame brought into the plate (its size (W, H)), zero
    where the frame does not reach. The transform is in pixel edges (a pixel spans [i, i + 1]); OpenCV
    warps pixel centres, so each axis's offset gains half its scale less one."""
    import cv2

    src = np.ascontiguousarray(image, np.float32)
    scale, (ox, oy) = transform.scale, transform.offset
    sx = sy = scale
    if scale < 1.0:  # area first, so a person made smaller keeps its edges without aliasing
        h, w = src.shape[:2]
        size = (max(int(round(w * scale)), 1), max(int(round(h * scale)), 1))
        src = resize(src, size, "area").reshape(size[1], size[0], -1)
        sx, sy = scale * w / size[0], scale * h / size[1]  # the shrunk frame's pixels into the plate's
    matrix = np.array([[sx, 0.0, ox + 0.5 * (sx - 1.0)], [0.0, sy, oy + 0.5 * (sy - 1.0)]])
    out = []
    for c in range(0, src.shape[2], 4):  # OpenCV warps up to 4 channels at a time
        warped = cv2.warpAffine(src[..., c:c + 4], matrix, plate_size, flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=(0.0,) * 4)
        out.append(warped.reshape(plate_size[1], plate_size[0], -1))
    return np.concatenate(out, axis=-1)


def composite_on_plate(plate_linear: np.ndarray, person_rgba: np.ndarray, shadow_share: np.ndarray | None,
                       transform: PlateTransform, blur: float = 0.0, focal_px: float = 0.0, sky: float = 0.0,
                       horizon: float | None = None, front: np.ndarray | None = None) -> PlateComposite:
    """The person (premultiplied RGBA, the frame's size) and the ground's shadow share (any size over
    the same frame; None: no shadow) composited into ``plate_linear`` (H, W, 3); the person's layer
    blurred by ``blur`` pixels (the plate's defocus where they stand, :mod:`viewer.plate.match`);
    with ``sky`` > 0 (the share of the ground's light a contact shadow hides) the ground around the
    feet darkened too (:func:`viewer.plate.contact.contact_shadow`, the plate's focal length ``focal_px``
    in its pixels, its ``horizon`` a fraction of its height), in the shadow layer; ``front`` (H, W), the
    matte of what of the plate stands in front of the person (its people nearer the camera,
    :func:`viewer.plate.people.in_front`), hides the person and their shadow there."""
    import cv2

    from viewer.plate.contact import REACH, contact_shadow

    h, w = plate_linear.shape[:2]
    fh, fw = person_rgba.shape[:2]
    # the work is done over the region the person's frame lands on (with the blur's and the contact
    # shadow's reach): the rest of the plate is the plate (a person a tenth of a 12-MP plate: ~1 % of it)
    x0, y0, x1, y1 = _landing(transform, (fw, fh), (w, h), 3.0 * blur + 2.0 + REACH * transform.scale * fh)
    out_image = plate_linear.astype(np.float32, copy=True)
    out_person = np.zeros((h, w, 4), np.float32)
    out_shadow = np.ones((h, w, 3), np.float32)
    if x0 >= x1 or y0 >= y1:  # the frame lands wholly off the plate
        return PlateComposite(out_image, out_person, out_shadow)
    local = PlateTransform(transform.scale, (transform.offset[0] - x0, transform.offset[1] - y0))
    size = (x1 - x0, y1 - y0)
    person = np.clip(np.nan_to_num(into_plate(person_rgba, local, size), nan=0.0, posinf=MAX_HALF), 0.0, MAX_HALF)
    if blur >= 0.3:  # premultiplied: the edge softens with the colour it carries, no dark or bright fringe
        person = cv2.GaussianBlur(person, (0, 0), float(blur))
    person[..., 3] = np.clip(person[..., 3], 0.0, 1.0)
    shadow = out_shadow[y0:y1, x0:x1]
    if shadow_share is not None:
        share = resize(np.ascontiguousarray(shadow_share, np.float32), (fw, fh), "linear")
        shadow[:] = np.clip(1.0 - np.nan_to_num(into_plate(share.reshape(fh, fw, -1), local, size), nan=0.0), 0.0, 1.0)
    horizon_px = None if horizon is None else horizon * h - y0  # in the region's rows
    contact = contact_shadow(person[..., 3], focal_px, sky, horizon_px) if sky > 0.0 and focal_px > 0.0 else None
    if contact is not None:  # the darker of the lights' shadow and the sky's share hidden at the feet
        np.minimum(shadow, contact[..., None], out=shadow)
    if front is not None:  # the plate's own people in front: the person behind them, and no shadow on them
        hidden = np.clip(front[y0:y1, x0:x1], 0.0, 1.0)[..., None]
        person *= 1.0 - hidden
        shadow[:] = hidden + (1.0 - hidden) * shadow
    out_image[y0:y1, x0:x1] = plate_linear[y0:y1, x0:x1] * shadow * (1.0 - person[..., 3:4]) + person[..., :3]
    out_person[y0:y1, x0:x1] = person
    return PlateComposite(out_image, out_person, out_shadow)


def _landing(transform: PlateTransform, frame_size: tuple[int, int], plate_size: tuple[int, int], margin: float):
    """(x0, y0, x1, y1): the plate's pixels the frame of ``frame_size`` lands on by ``transform``, grown by
    ``margin`` pixels, within the plate."""
    (ox, oy), s = transform.offset, transform.scale
    x0, y0 = int(np.floor(ox - margin)), int(np.floor(oy - margin))
    x1, y1 = int(np.ceil(ox + s * frame_size[0] + margin)), int(np.ceil(oy + s * frame_size[1] + margin))
    return max(x0, 0), max(y0, 0), min(x1, plate_size[0]), min(y1, plate_size[1])

