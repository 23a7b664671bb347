"""The pose's landmarks drawn as masks the matte is decided with: the person's height, the bones, the face,
the head and the gaps between limbs and body (MediaPipe's pose landmarks, :mod:`viewer.photo.segmentation`)."""

from __future__ import annotations

import numpy as np

# The pose model's bones (MediaPipe's POSE_CONNECTIONS without the fingers, 17-22, which it guesses)
BONES = ((0, 1), (0, 4), (1, 2), (2, 3), (3, 7), (4, 5), (5, 6), (6, 8), (9, 10), (11, 12), (11, 13), (11, 23),
         (12, 14), (12, 24), (13, 15), (14, 16), (23, 24), (23, 25), (24, 26), (25, 27), (26, 28), (27, 29),
         (27, 31), (28, 30), (28, 32), (29, 31), (30, 32))
TORSO = (11, 12, 24, 23)
FACE = tuple(range(11))  # MediaPipe's face landmarks (nose, eyes, ears, mouth)
# Where limbs, hair and body meet, the segmentation fills the gaps between them (the background
# seen between an arm and the body, between the legs, between hair and shoulder): these polygons
# of landmarks are never the person for sure, whatever their depth inside the segmentation
# ("hips" is the middle of the two hips).
GAPS = ((11, 13, 15, 23), (12, 14, 16, 24),  # each arm and the side of the body
        ("hips", 25, 27, 28, 26),  # between the legs
        (7, 11, 12), (8, 12, 11))  # each ear, its shoulder and the other (hair over the shoulders)


def person_height(mask: np.ndarray) -> int:
    """Rows the mask spans (at least 1)."""
    rows = np.flatnonzero(mask.any(axis=1))
    return int(rows[-1] - rows[0] + 1) if rows.size else 1


def bones_mask(landmarks: dict, size: tuple[int, int], thickness: int) -> np.ndarray:
    """(H, W) bool: the pose's bones, torso and face drawn at ``size`` = (w, h) from landmarks
    (index -> normalized (x, y))."""
    import cv2

    w, h = size
    out = np.zeros((h, w), np.uint8)
    pts = {i: (int(round(x * w)), int(round(y * h))) for i, (x, y) in landmarks.items()}
    for a, b in BONES:
        if a in pts and b in pts:
            cv2.line(out, pts[a], pts[b], 1, max(1, thickness))
    if all(i in pts for i in TORSO):
        cv2.fillPoly(out, [np.array([pts[i] for i in TORSO], np.int32)], 1)
    face = face_mask(landmarks, size)
    return (out > 0) | face if face is not None else out > 0


def face_mask(landmarks: dict, size: tuple[int, int]) -> np.ndarray | None:
    """(H, W) bool: the convex hull of the pose's face landmarks (``FACE``) at ``size`` = (w, h);
    None when fewer than three of them are seen."""
    import cv2

    w, h = size
    face = [(int(round(x * w)), int(round(y * h))) for i, (x, y) in landmarks.items() if i in FACE]
    if len(face) < 3:
        return None
    out = np.zeros((h, w), np.uint8)
    cv2.fillPoly(out, [cv2.convexHull(np.array(face, np.int32))], 1)
    return out > 0


HEAD_TOP = 1.75  # eye-to-mouth lengths above the eyes: the top of the head (about 1.9), a little inside it
HEAD_CHIN = 0.8  # eye-to-mouth lengths below the mouth: the chin
HEAD_BROWS = 0.4  # eye-to-mouth lengths above the eyes: where the crown begins (the brows; the temples left to the band)
HEAD_WIDE = 0.65  # of the distance between the ears: the head's half-width (1.2 eye-to-mouth lengths without both ears)


def head_mask(landmarks: dict, size: tuple[int, int]) -> np.ndarray | None:
    """(H, W) bool at ``size`` = (w, h): the crown, the ellipse of the head the pose's face landmarks
    give (from ``HEAD_CHIN`` below the mouth to ``HEAD_TOP`` above the eyes, along the face's own up,
    ``HEAD_WIDE`` of the ears' distance to each side) above the brows (``HEAD_BROWS``); None without both
    eyes and the mouth. Within the segmentation it is the person for sure (:func:`trimap`): dark hair against a dark background has the
    background's colours, and the band's colour cut took the top of a head off (a man relit bald)."""
    import cv2

    w, h = size
    pts = {i: np.array([x * w, y * h]) for i, (x, y) in landmarks.items()}
    if not all(i in pts for i in (2, 5, 9, 10)):
        return None
    eyes, mouth = 0.5 * (pts[2] + pts[5]), 0.5 * (pts[9] + pts[10])
    up = eyes - mouth
    length = float(np.linalg.norm(up))
    if length < 1.0:
        return None
    up /= length
    top, chin = eyes + HEAD_TOP * length * up, mouth - HEAD_CHIN * length * up
    wide = HEAD_WIDE * float(np.linalg.norm(pts[7] - pts[8])) if 7 in pts and 8 in pts else 1.2 * length
    centre, tall = 0.5 * (top + chin), 0.5 * float(np.linalg.norm(top - chin))
    out = np.zeros((h, w), np.uint8)
    angle = float(np.degrees(np.arctan2(up[0], -up[1])))  # the face's up from the image's
    cv2.ellipse(out, (int(round(centre[0])), int(round(centre[1]))), (max(int(round(wide)), 1), max(int(round(tall)), 1)),
                angle, 0, 360, 1, -1)
    # above the brows only: the crown and its hair; beside the face and the temples (a turned head's far side,
    # its ears) the segmentation spills over the background, and the band decides there
    xs, ys = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    return (out > 0) & ((xs - eyes[0]) * up[0] + (ys - eyes[1]) * up[1] > HEAD_BROWS * length)


def gaps_mask(landmarks: dict, size: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: the ``GAPS`` polygons at ``size`` = (w, h) whose landmarks are all seen."""
    import cv2

    w, h = size
    pts = {i: (x * w, y * h) for i, (x, y) in landmarks.items()}
    if 23 in pts and 24 in pts:
        pts["hips"] = tuple(0.5 * (a + b) for a, b in zip(pts[23], pts[24]))
    out = np.zeros((h, w), np.uint8)
    for polygon in GAPS:
        if all(i in pts for i in polygon):
            cv2.fillPoly(out, [np.round([pts[i] for i in polygon]).astype(np.int32)], 1)
    return out > 0
