"""How shiny each region of the person may be: skin keeps the networks' sheen, the rest is matte.

On real photos the inverse-rendering network's roughness is nearly uniform (about 0.55, GGX alpha
0.3 on everything, its guess when unsure), and with Disney's F0 of 0.035 that lobe turns dark cloth
into glossy latex under a low sun, where the diffuse term of a dark albedo is small and the
specular's Fresnel large. Cloth is rough (the training data's cotton and denim 0.7 to 0.9), so a
class prior decides: the photo's skin, told by its colour against the face's (the pose landmarks'
face polygon: a Gaussian of the skin's log-chromaticity there; nothing much darker than the face),
keeps the network's roughness; the rest is made at least ``MATTE_ROUGHNESS``. Hair and leather lose their moving highlight with it
(the photo's own highlights stay in the detail albedo). Without a face (a photo the pose model does
not find, a synthetic scene), nothing changes. docs/photos.md shows dark cloth under a low sun
before and after, and measures the prior on held-out pairs.

The networks' specular map is nearly uniform too, and the photo bounds it: a sheen adds to every
channel, so where the photo's colour is saturated (a red jacket with no green in it) it has
little sheen, whatever the map says. :func:`bounded_sheen` scales the map there, once the photo's
own light is known; under a new light such a surface keeps its colour (a uniform white light
turned that jacket pink).
"""

from __future__ import annotations

import numpy as np

from viewer.photo.detail import luminance, masked_lowpass, sheen_room
from viewer.photo.pose_masks import face_mask
from viewer.resize import mask_normalized_resize, resize

MATTE_ROUGHNESS = 0.85  # the roughness floor of what is not skin (cotton and denim: 0.7 to 0.9)
SKIN_DISTANCE = 3.0  # Mahalanobis distance in the skin's log-chromaticity where skin turns to not skin
MIN_FACE_PIXELS = 50  # fewer face pixels than this: no skin model
SKIN_DARKEST = 0.2  # of the face's median luminance: darker is not skin (black cloth's chromaticity is noise)
FACE_WIDTH_MM = 145.0  # an adult face's width across the face mesh's outline (at the ears: 140-150 mm)
PERSON_HEIGHT_MM = 1700.0  # a standing adult, for the scale of a photo without a face


def _log_chroma(rgb: np.ndarray) -> np.ndarray:
    rgb = np.maximum(np.asarray(rgb, np.float64), 1e-4)
    return np.stack([np.log(rgb[..., 0] / rgb[..., 1]), np.log(rgb[..., 2] / rgb[..., 1])], axis=-1)


def colour_distance(rgb: np.ndarray, sample: np.ndarray) -> np.ndarray:
    """(H, W): each pixel's Mahalanobis distance, in log-chromaticity, from the colours of the
    pixels ``sample`` (H, W) bool of ``rgb`` (a Gaussian of them about their median)."""
    chroma = _log_chroma(rgb)
    c = chroma[sample]
    centre = np.median(c, axis=0)
    spread = np.cov((c - centre).T) + np.eye(2) * 1e-3
    d = chroma - centre
    return np.sqrt(np.einsum("...i,ij,...j->...", d, np.linalg.inv(spread), d))


def skin(foreground: np.ndarray, alpha: np.ndarray, landmarks: dict) -> np.ndarray | None:
    """(H, W) float32 in [0, 1]: how much each pixel of the person looks like the skin of its face
    (1 at the face's own colour, 0 beyond ``SKIN_DISTANCE``); None without a face to learn from."""
    h, w = alpha.shape
    face = face_mask(landmarks, (w, h))
    if face is None:
        return None
    sample = face & (alpha > 0.9)
    if sample.sum() < MIN_FACE_PIXELS:
        return None
    distance = colour_distance(foreground, sample)
    brightness = luminance(np.asarray(foreground, np.float64))
    lit = brightness >= SKIN_DARKEST * np.median(brightness[sample])  # a dark pixel's chromaticity is noise
    return (np.clip(1.0 - distance / SKIN_DISTANCE, 0.0, 1.0) * lit * (alpha > 0)).astype(np.float32)


def matte_roughness(roughness: np.ndarray, skin_share: np.ndarray | None) -> np.ndarray:
    """The roughness map with what is not skin at least ``MATTE_ROUGHNESS`` (unchanged without a skin map)."""
    if skin_share is None:
        return roughness
    floor = MATTE_ROUGHNESS * (1.0 - skin_share)
    return np.maximum(roughness, floor).astype(np.float32)


def skin_mm(face_width_px: float | None, person_height_px: float) -> float:
    """Millimetres of the person one frame pixel spans, for the light scattered under the skin
    (:mod:`viewer.gl.skin_pass`): from the face's width when a face was found (the face mesh's
    outline, ``FACE_WIDTH_MM``), else from the matte's height read as a standing adult's."""
    if face_width_px is not None and face_width_px > 0:
        return FACE_WIDTH_MM / float(face_width_px)
    return PERSON_HEIGHT_MM / max(float(person_height_px), 1.0)


def bounded_sheen(scene, specular_old: np.ndarray, colour: np.ndarray, network_px: float):
    """(``scene`` with its specular map scaled where the photo leaves no room for the sheen, the
    photo's sheen under its own lights ``specular_old`` (H, W, 3 at the frame) scaled alike, the
    share of the person whose sheen was lessened). The room (:func:`viewer.photo.detail.sheen_room`)
    is read from the photo's ``colour`` (linear, the frame's size) at the maps' level of detail (a
    low-pass of ``network_px`` frame pixels); the map takes its least over the frame pixels one work
    pixel's shading reaches (its footprint and the bilinear reach around it), so that no frame pixel
    gets more sheen than its photo allows; the photo's sheen is scaled by that map brought back."""
    from dataclasses import replace

    import cv2

    alpha = scene.frame.alpha
    person = alpha > 0.5
    room = sheen_room(masked_lowpass(colour, person, network_px), specular_old)
    side = 2 * int(np.ceil(alpha.shape[1] / scene.width)) + 1
    least = cv2.erode(room, np.ones((side, side), np.uint8))
    work = np.clip(mask_normalized_resize(least[..., None], alpha, (scene.width, scene.height))[..., 0], 0.0, 1.0)
    share = np.clip(resize(work, (alpha.shape[1], alpha.shape[0])), 0.0, 1.0)
    bounded = replace(scene, specular=np.where(scene.mask, scene.specular * work, 0.0).astype(np.float32)).validate(
        only=frozenset({"specular"}))
    lessened = float((share[person] < 0.99).mean()) if person.any() else 0.0
    return bounded, (specular_old * share[..., None]).astype(np.float32), lessened
