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
        src = cv2.resize(src, size, interpolation=cv2.INTER_AREA).reshape(size[1], size[0], -1)
        sx, sy = scale * w / size[0], scale * h / size[1]  # the shrunk frame's pixels into the plate's
    matrix = np.array([[sx, 0.0, ox + 0.5 * (sx - 1.0)], [0.0, sy, oy + 0.5 * (sy - 1.0)]])
    out = []
    for c in range(0, src.shape[2], 4):  # OpenCV warps up to 4 channels at a time
        warped = cv2.warpAffine(src[..., c:c + 4], matrix, plate_size, flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=(0.0,) * 4)
        out.append(warped.reshape(plate_size[1], plate_size[0], -1))
    return np.concatenate(out, axis=-1)


def composite_on_plate(plate_linear: np.ndarray, person_rgba: np.ndarray, shadow_share: np.ndarray | None,
                       transform: PlateTransform, blur: float = 0.0, focal_px: float = 0.0, sky: float = 0.0) -> PlateComposite:
    """The person (premultiplied RGBA, the frame's size) and the ground's shadow share (any size over
    the same frame; None: no shadow) composited into ``plate_linear`` (H, W, 3); the person's layer
    blurred by ``blur`` pixels (the plate's defocus where they stand, :mod:`viewer.plate.plate_match`);
    with ``sky`` > 0 (the share of the ground's light a contact shadow hides) the ground around the
    feet darkened too (:func:`viewer.plate.contact.contact_shadow`, the plate's focal length ``focal_px``
    in its pixels), in the shadow layer."""
    import cv2

    from viewer.plate.contact import contact_shadow

    h, w = plate_linear.shape[:2]
    person = np.clip(np.nan_to_num(into_plate(person_rgba, transform, (w, h)), nan=0.0, posinf=MAX_HALF), 0.0, MAX_HALF)
    if blur >= 0.3:  # premultiplied: the edge softens with the colour it carries, no dark or bright fringe
        person = cv2.GaussianBlur(person, (0, 0), float(blur))
    person[..., 3] = np.clip(person[..., 3], 0.0, 1.0)
    if shadow_share is not None:
        fh, fw = person_rgba.shape[:2]
        share = cv2.resize(np.ascontiguousarray(shadow_share, np.float32), (fw, fh), interpolation=cv2.INTER_LINEAR)
        shadow = np.clip(1.0 - np.nan_to_num(into_plate(share.reshape(fh, fw, -1), transform, (w, h)), nan=0.0), 0.0, 1.0)
        if shadow.shape[2] == 1:
            shadow = np.repeat(shadow, 3, axis=2)
    else:
        shadow = np.ones((h, w, 3), np.float32)
    contact = contact_shadow(person[..., 3], focal_px, sky) if sky > 0.0 and focal_px > 0.0 else None
    if contact is not None:  # the darker of the lights' shadow and the sky's share hidden at the feet
        shadow = np.minimum(shadow, contact[..., None])
    image = plate_linear * shadow * (1.0 - person[..., 3:4]) + person[..., :3]
    return PlateComposite(image.astype(np.float32), person.astype(np.float32), shadow.astype(np.float32))
