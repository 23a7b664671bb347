"""The automatic person segmentation on real photos: close to the hand-made masks, its landmarks,
the largest of several people, and one clear line when there is nobody (the matte made from it:
tests/test_matting.py)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SHARED_DATA

from viewer.errors import InputError
from viewer.files.imageio import linear_to_srgb
from viewer.lab.bench.photos import mask_iou, read_reference_mask
from viewer.lighting.envmap import load_envmap
from viewer.photo.frames import read_photo
from viewer.photo.segmentation import find_person
from viewer.resize import resize

PHOTOS = SHARED_DATA / "photos"


@pytest.mark.parametrize("stem", ["unsplash-1507274733827", "unsplash-1535323700481"])
def test_segmentation_matches_the_hand_made_mask(stem):
    photo = read_photo(PHOTOS / f"{stem}.jpg", [])
    notes = []
    person = find_person(photo, stem, notes)
    seg = person.segmentation
    assert seg.shape == photo.shape[:2] and seg.dtype == np.float32
    assert mask_iou(seg, read_reference_mask(PHOTOS / f"{stem}.mask.png")) > 0.96
    # the landmarks the matte's trimap needs: face, shoulders, hips, knees and feet, inside the photo
    assert {0, 11, 12, 23, 24, 25, 26, 27, 28} <= set(person.landmarks)
    assert all(0 <= x <= 1 and 0 <= y <= 1 for x, y in person.landmarks.values())
    assert notes == []


def two_people() -> tuple[np.ndarray, int]:
    """Two real photos side by side, the right one's person smaller (and the column they meet at)."""
    a = read_photo(PHOTOS / "unsplash-1535323700481.jpg", [])
    b = read_photo(PHOTOS / "unsplash-1507274733827.jpg", [])
    big = resize(a, (a.shape[1] * 1000 // a.shape[0], 1000))
    small = resize(b, (b.shape[1] * 600 // b.shape[0], 600))
    two = np.zeros((1000, big.shape[1] + small.shape[1], 3), np.uint8)
    two[:, :big.shape[1]] = big
    two[400:, big.shape[1]:] = small
    return two, big.shape[1]


def test_the_largest_of_several_people_is_kept_with_a_note():
    two, split = two_people()
    notes = []
    matte = find_person(two, "two people", notes).segmentation > 0.5
    assert any("2 people" in n and "the largest" in n for n in notes)
    assert matte[:, :split].sum() > 0.95 * matte.sum()  # the larger person, alone


def test_in_a_clip_the_person_followed_is_kept_not_the_largest():
    """A bystander nearer the camera (larger) stays out: the person the clip follows (chosen by a
    point on them) is segmented, alone; someone who is not them is never relit in their place."""
    from viewer.photo.person_track import PersonTrack, choose
    from viewer.photo.segmentation import frame_people

    two, split = two_people()
    h, w = two.shape[:2]
    _, _, parts = frame_people(two)
    assert len(parts) == 2
    pick = choose(parts, ((split + 0.5 * (w - split)) / w, 0.8))  # a point on the right-hand person
    assert parts[pick].box[0] > 0.9 * split / w
    assert choose(parts) != pick  # unasked: the larger, more central one
    chosen = {"box": list(parts[pick].box), "signature": parts[pick].signature.tolist(), "frame": 0}
    track = PersonTrack(chosen)
    track.at(1)
    notes = []
    matte = find_person(two, "two people", notes, follow=track).segmentation > 0.5
    assert matte[:, split:].sum() > 0.95 * matte.sum() and matte[:, split:].sum() > 0.1 * 600 * (w - split)  # the person, whole
    assert track.last_index == 1
    # the person gone (only the larger one left, far from where they were): no one relit, one line
    alone = two.copy()
    alone[:, split:] = 0
    track.at(40)
    with pytest.raises(InputError, match="not in the picture"):
        find_person(alone, "one left", [], follow=track)
    # --people all: both relit, the person followed lending the landmarks
    track.at(41)
    both = find_person(two, "two people", [], follow=track, everyone_too=True).segmentation > 0.5
    assert both[:, :split].sum() > 0.3 * both.sum() and both[:, split:].sum() > 0.1 * both.sum()


def test_no_person_is_one_clear_line():
    env = load_envmap(SHARED_DATA / "hdri" / "st_fagans_interior_1k.hdr").pixels  # a room, nobody in it
    room = (linear_to_srgb(env / np.percentile(env, 90)) * 255).astype(np.uint8)
    with pytest.raises(InputError, match="no person found") as info:
        find_person(room, "room.jpg")
    assert info.value.path == "room.jpg"


def test_shoes_split_from_the_legs_are_the_persons_feet():
    """Dark shoes on a dark floor come out of the selfie model as parts of their own under the legs: they
    are the person's (their box reaches the soles, the box the pose model is shown), while a small part
    farther off, or above the person, stays a part of its own."""
    from viewer.photo.segmentation import _people

    mask = np.zeros((500, 700), bool)
    mask[100:400, 100:200] = True  # the person down to the trouser hems
    mask[415:450, 100:140] = mask[420:450, 160:200] = True  # their shoes
    mask[420:450, 500:530] = True  # someone small, far to the side
    mask[40:60, 140:165] = True  # a piece above the head
    parts = _people(mask, everyone=True)
    (x, y, w, h), pixels = parts[0]
    assert (x, y, w, h) == (100, 100, 100, 350) and pixels[440, 120] and pixels[440, 180]
    assert not pixels[440, 510] and not pixels[50, 150]
    assert sorted(p[0] for p in parts[1:]) == [(140, 40, 25, 20), (500, 420, 30, 30)]
