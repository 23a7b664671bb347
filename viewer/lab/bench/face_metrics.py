"""What a portrait retoucher looks at first, as numbers: holes in the face's skin and
speckle on face and limbs, of a relit image against its photo.

- **The face's skin** (:func:`face_skin`): MediaPipe's full-range face detector on the photo, a crop
  of twice its box at 384 px, the 468-point mesh (:func:`viewer.photo.face.find_faces`); the skin
  is the face oval less the eyes, brows and lips, each grown 2 px.
- **Holes** (:func:`holes`): the share of that skin where the relit linear luminance over the
  photo's (both blurred by a Gaussian of sigma 1 px) is below ``HOLE_SHARE`` of that ratio's median
  over the skin: a black wedge, a block under the nose, a cast shadow no skin would keep black.
- **Speckle** (:func:`speckle`): on a region, the standard deviation of the fine detail (the
  luminance minus its Gaussian blur of sigma 1.5 px, over its blur of sigma 6 px) in the relit
  image over the same in the photo: above 1, noise the photo does not have was amplified.
- **Limb skin** (:func:`limb_skin`): pixels of the person, away from the face and from the matte's
  edge, whose log-chromaticity is the face skin's (a Gaussian of the skin's colour, as
  :mod:`viewer.photo.gloss` tells skin, within 1.5 of its Mahalanobis distance), about as bright as
  the face's skin.
"""

from __future__ import annotations

import numpy as np

from viewer.lab.bench.metrics import luminance

HOLE_SHARE = 0.35  # of the median relit / photo ratio over the skin: below it, a hole
HOLE_BLUR = 1.0  # px: both images blurred before the ratio
FINE_SIGMA, COARSE_SIGMA = 1.5, 6.0  # px: the speckle's fine detail and its normalization
FEATURE_GROW = 2  # px the eyes, brows and lips are grown before they are taken out of the skin
SKIN_DISTANCE = 1.5  # Mahalanobis distance in log-chromaticity: limb skin is this near the face's
SKIN_BRIGHTNESS = (0.35, 2.5)  # of the face skin's median luminance: limb skin lies between
LIMB_EDGE = 6  # px: limb skin this far inside the matte at least
MIN_PIXELS = 50  # a region of fewer pixels gives no figure


def _part(points: np.ndarray, connections, shape, grow: int = 0) -> np.ndarray:
    """(H, W) bool: the convex hull of the landmarks a MediaPipe connection set names, grown."""
    import cv2

    idx = sorted({i for edge in connections for i in edge})
    hull = cv2.convexHull(np.round(points[idx, :2]).astype(np.int32))
    out = np.zeros(shape, np.uint8)
    cv2.fillPoly(out, [hull], 1)
    if grow:
        out = cv2.dilate(out, np.ones((2 * grow + 1, 2 * grow + 1), np.uint8))
    return out > 0


def face_skin(photo_srgb: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, dict] | None:
    """(the face's skin (H, W) bool, a record) for the largest face on the person of ``photo_srgb``
    (uint8) whose matte is ``alpha``; None when no face is found."""
    from mediapipe.python.solutions import face_mesh_connections as fm

    from viewer.photo.face import find_faces

    faces = find_faces(photo_srgb, alpha)
    if not faces:
        return None
    points = faces[0].points
    shape = alpha.shape
    features = np.zeros(shape, bool)
    for part in (fm.FACEMESH_LEFT_EYE, fm.FACEMESH_RIGHT_EYE, fm.FACEMESH_LEFT_EYEBROW, fm.FACEMESH_RIGHT_EYEBROW,
                 fm.FACEMESH_LIPS):
        features |= _part(points, part, shape, FEATURE_GROW)
    oval = _part(points, fm.FACEMESH_FACE_OVAL, shape)
    skin = oval & ~features & (alpha > 0.5)
    return skin, {"faces": len(faces), "width_px": round(faces[0].width, 1), "skin_pixels": int(skin.sum()),
                  "oval": oval}


def _blur(image: np.ndarray, sigma: float) -> np.ndarray:
    import cv2

    k = 2 * int(np.ceil(3 * sigma)) + 1
    return cv2.GaussianBlur(image, (k, k), sigma, borderType=cv2.BORDER_REFLECT)


def holes(relit: np.ndarray, photo: np.ndarray, skin: np.ndarray) -> float | None:
    """The share of ``skin`` where blurred relit / photo luminance (linear RGB, same frame) is below
    ``HOLE_SHARE`` of its median there; None for a skin of under ``MIN_PIXELS``."""
    if skin.sum() < MIN_PIXELS:
        return None
    yr, yp = _blur(luminance(relit), HOLE_BLUR), _blur(luminance(photo), HOLE_BLUR)
    ratio = yr[skin] / np.maximum(yp[skin], 1e-6)
    return float((ratio < HOLE_SHARE * np.median(ratio)).mean())


def fine_detail(image: np.ndarray) -> np.ndarray:
    """(Y - blur_1.5(Y)) / blur_6(Y) of the linear luminance."""
    y = luminance(image)
    return (y - _blur(y, FINE_SIGMA)) / np.maximum(_blur(y, COARSE_SIGMA), 1e-4)


def speckle(relit: np.ndarray, photo: np.ndarray, region: np.ndarray) -> float | None:
    """The relit image's fine-detail standard deviation over the photo's, over ``region``; None for a
    region of under ``MIN_PIXELS``."""
    if region.sum() < MIN_PIXELS:
        return None
    return float(fine_detail(relit)[region].std() / max(float(fine_detail(photo)[region].std()), 1e-9))


def limb_skin(photo: np.ndarray, alpha: np.ndarray, skin: np.ndarray, oval: np.ndarray) -> np.ndarray:
    """(H, W) bool: the person's visible skin off the face (arms, legs, hands), told by the face
    skin's colour (``photo`` linear RGB)."""
    import cv2

    from viewer.photo.gloss import colour_distance

    distance = colour_distance(photo, skin)
    y = luminance(photo)
    face_y = float(np.median(y[skin]))
    lit = (y > SKIN_BRIGHTNESS[0] * face_y) & (y < SKIN_BRIGHTNESS[1] * face_y)
    core = cv2.erode((alpha > 0.9).astype(np.uint8), np.ones((2 * LIMB_EDGE + 1,) * 2, np.uint8)) > 0
    face = cv2.dilate(oval.astype(np.uint8), np.ones((25, 25), np.uint8)) > 0
    return (distance < SKIN_DISTANCE) & lit & core & ~face
