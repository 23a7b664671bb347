"""What the person found in a photo says of the photo and its mask: a pose lying sideways or upside
down (a photo that lost its EXIF rotation) and a mask that is the background's."""

from __future__ import annotations

import numpy as np

from viewer.errors import InputError


def orientation_note(landmarks: dict) -> str | None:
    """What to say when the pose lies sideways or upside down in the photo (its head beside or below
    its hips, and its ankles not below them: a photo whose EXIF rotation was lost; someone bent over on
    their feet is upright), else None. The ground and its shadow take the photo's bottom for the floor."""
    needed = (0, 11, 12, 23, 24)  # nose, shoulders, hips
    if not all(i in landmarks for i in needed):
        return None
    head = np.mean([landmarks[i] for i in (0, 11, 12)], axis=0)
    hips = np.mean([landmarks[i] for i in (23, 24)], axis=0)
    dx, dy = hips - head  # image coordinates: y down; upright, the hips are below the head
    if dy > abs(dx):
        return None
    ankles = [landmarks[i] for i in (27, 28) if i in landmarks]
    if ankles and -dy <= abs(dx):  # head beside the hips: lying down, or bent over on legs that stand (feet below the hips)
        lx, ly = np.mean(ankles, axis=0) - hips
        if ly > abs(lx):
            return None
    where = "upside down" if -dy > abs(dx) else f"sideways (head to the {'left' if dx > 0 else 'right'})"
    return (f"the person is {where} in the photo: if the photo lost its rotation (EXIF), turn it upright; the ground "
            "and its shadow take the photo's bottom for the floor")


INVERTED_BORDER = 0.5  # a mask holding more of the image's border than this share is the background's
INVERTED_POSE = 2 / 3  # or outside of which lie more than this share of the pose's landmarks


def check_not_inverted(mask: np.ndarray, landmarks: dict, path) -> None:
    """Refuse, in one line, a mask that is the background's (white where the person is not): most
    of the image's border inside it (a mask of the whole photo is the user's choice: noted later),
    or most of the pose's landmarks outside it."""
    person = mask > 0.5
    if person.all():
        return
    border = np.concatenate([person[0], person[-1], person[:, 0], person[:, -1]])
    h, w = person.shape
    inside = [person[min(int(y * h), h - 1), min(int(x * w), w - 1)] for x, y in landmarks.values() if 0 <= x < 1 and 0 <= y < 1]
    if border.mean() > INVERTED_BORDER or (len(inside) >= 5 and 1 - np.mean(inside) > INVERTED_POSE):
        why = (f"{border.mean():.0%} of the image's border is inside it" if border.mean() > INVERTED_BORDER
               else f"{1 - np.mean(inside):.0%} of the person's pose lies outside it")
        raise InputError(path, f"looks inverted: {why} (a person mask is white on the person, black elsewhere): "
                               "invert it and give it again")
