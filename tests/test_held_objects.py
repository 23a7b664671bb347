"""What the person holds or stands on is kept with the person (viewer/photo/held_objects.py): a stick
leaving the hand and a board under the feet on a known picture, the skier's poles on a real photo;
background structure touching the feet (a stair's edge), a shadow-grey patch that barely stands out
and things that touch no hand or foot are not kept; a mask file that includes an object keeps it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from conftest import SHARED_DATA

from viewer.photo import held_objects, matting, trimap
from viewer.photo.pose_masks import person_height

H, W = 400, 300


def _picture(seed=0):
    """A person (a skin-coloured body, arms and legs) on a textured grey-green backdrop, with its
    landmarks (MediaPipe's indices: wrists 15/16, ankles 27/28, toes 31/32)."""
    import cv2

    rng = np.random.default_rng(seed)
    image = np.clip(np.array([0.45, 0.5, 0.42]) + rng.normal(0, 0.02, (H, W, 3)), 0, 1)
    person = np.zeros((H, W), np.uint8)
    cv2.ellipse(person, (150, 70), (22, 28), 0, 0, 360, 1, -1)  # head
    cv2.rectangle(person, (115, 100), (185, 230), 1, -1)  # body
    cv2.line(person, (115, 110), (70, 200), 1, 14)  # arms
    cv2.line(person, (185, 110), (230, 200), 1, 14)
    cv2.line(person, (130, 230), (125, 350), 1, 18)  # legs
    cv2.line(person, (170, 230), (175, 350), 1, 18)
    person = person > 0
    image[person] = [0.8, 0.6, 0.5]
    landmarks = {15: (70 / W, 200 / H), 16: (230 / W, 200 / H), 27: (125 / W, 350 / H), 28: (175 / W, 350 / H),
                 31: (120 / W, 358 / H), 32: (180 / W, 358 / H)}
    return image, person, landmarks


def _line(shape, a, b, thickness):
    import cv2

    out = np.zeros(shape, np.uint8)
    cv2.line(out, a, b, 1, thickness)
    return out > 0


def test_a_stick_from_the_hand_and_a_board_under_the_feet_are_kept():
    image, person, landmarks = _picture()
    stick = _line(person.shape, (70, 200), (30, 330), 4) & ~person  # a ski pole: dark, from the left hand
    board = _line(person.shape, (90, 362), (215, 362), 6) & ~person  # a skateboard under both feet
    image[stick] = [0.05, 0.05, 0.06]
    image[board] = [0.95, 0.1, 0.05]
    found = held_objects.find_objects(image, person, landmarks, person_height(person))
    assert found[stick].mean() > 0.9 and found[board].mean() > 0.9
    assert not (found & person).any()
    assert (found & ~stick & ~board).sum() < 0.15 * (stick.sum() + board.sum())  # their closed gaps at most


def test_what_touches_no_hand_or_foot_and_what_runs_on_is_not_kept():
    """(A line seen only between the legs would be kept like a board: nothing tells them apart.)"""
    image, person, landmarks = _picture(1)
    apart = _line(person.shape, (260, 40), (280, 120), 5)  # a dark post, touching nothing
    stair = _line(person.shape, (0, 361), (W - 1, 361), 3) & ~person  # a kerb's edge under both feet, frame to frame
    image[apart] = [0.05, 0.05, 0.05]
    image[stair] = [0.1, 0.1, 0.1]
    found = held_objects.find_objects(image, person, landmarks, person_height(person))
    assert not found[apart].any()
    assert found[stair].mean() < 0.05


def test_a_patch_that_barely_stands_out_is_not_kept():
    """A soft contact shadow at the feet, a little darker than the floor's texture, stays the floor's."""
    image, person, landmarks = _picture(2)
    shadow = _line(person.shape, (95, 362), (205, 362), 10) & ~person
    image[shadow] *= 0.8
    found = held_objects.find_objects(image, person, landmarks, person_height(person))
    assert found[shadow].mean() < 0.05


def test_nothing_held_adds_nothing():
    image, person, landmarks = _picture(3)
    found = held_objects.find_objects(image, person, landmarks, person_height(person))
    assert not found.any()
    assert not held_objects.find_objects(image, person, {}, person_height(person)).any()
    assert not held_objects.find_objects(image, np.zeros_like(person), landmarks, 1).any()


def test_the_held_objects_are_found_at_any_resolution():
    """held_objects works where the person is SOLVE_HEIGHT tall and brings the objects back to the photo's size."""
    import cv2

    image, person, landmarks = _picture()
    stick = _line(person.shape, (70, 200), (30, 330), 4) & ~person
    image[stick] = [0.05, 0.05, 0.06]
    big = cv2.resize((image * 255).astype(np.uint8), (W * 4, H * 4), interpolation=cv2.INTER_LINEAR)
    big_person = cv2.resize(person.astype(np.uint8), (W * 4, H * 4), interpolation=cv2.INTER_NEAREST) > 0
    big_stick = cv2.resize(stick.astype(np.uint8), (W * 4, H * 4), interpolation=cv2.INTER_NEAREST) > 0
    found = held_objects.held_objects(big, big_person, landmarks, person_height(big_person))
    assert found.shape == big_person.shape
    assert found[big_stick].mean() > 0.8


SKIER = SHARED_DATA / "eval-photos" / "mmpose_coco_000000000785_skier.jpg"


def test_the_skiers_poles_stay_with_her():
    """On the real photo (640x425): points along both poles (from the hands to the baskets) are
    the person's in the automatic matte; the segmentation alone cut them away."""
    from viewer.photo.frames import read_photo
    from viewer.photo.segmentation import find_person

    photo = read_photo(SKIER, [])
    person = find_person(photo, SKIER)
    matte = matting.automatic_matte(photo, person)
    poles = (((297, 208), (328, 302)), ((480, 218), (553, 319)))  # (x, y): below each glove to above each basket
    for (x0, y0), (x1, y1) in poles:
        t = np.linspace(0, 1, 20)
        xs, ys = np.round(x0 + t * (x1 - x0)).astype(int), np.round(y0 + t * (y1 - y0)).astype(int)
        near = np.array([matte.alpha[y - 1:y + 2, x - 1:x + 2].max() for x, y in zip(xs, ys)])
        assert (near > 0.5).mean() > 0.8, near
        assert person.segmentation[ys, xs].mean() < 0.2  # what the pose model's segmentation says
    assert matte.record["held_px"] == int(matte.held.sum()) > 0
    # what she holds frames nothing: the networks' square and the maps' size are her body's
    assert not (matte.body & matte.held).any() and (matte.body | matte.held).sum() >= (matte.alpha > 0.5).sum()


def test_a_mask_that_includes_an_object_keeps_it():
    image, person, _ = _picture()
    stick = _line(person.shape, (70, 200), (30, 330), 4) & ~person
    photo = (image * 255).astype(np.uint8)
    matte = matting.mask_matte(photo, (person | stick).astype(np.float32))
    assert (matte.alpha[stick] > 0.5).mean() > 0.8


def test_in_a_clip_an_object_is_kept_from_its_second_frame_in_a_row():
    """Found frame by frame, held objects came and went (a shoe's shard, a piece of a sign in one frame
    of a street clip): in a clip an object is kept once the frame before found it too, carried here
    (within 1 % of the frame); a find of one frame alone is not kept. A photo, or a shot's first
    frame, keeps what it finds."""
    stick = _line((H, W), (70, 200), (30, 330), 4)
    board = _line((H, W), (90, 362), (215, 362), 6)
    found = stick | board
    kept = matting.confirmed(found, _line((H, W), (72, 203), (32, 333), 3))  # the stick, moved 3 px: seen before
    assert (kept == stick).all()
    assert not matting.confirmed(found, np.zeros((H, W), bool)).any()
    assert not matting.confirmed(np.zeros((H, W), bool), found).any()
    assert not matting.confirmed(board, _line((H, W), (90, 330), (215, 330), 6)).any()  # 32 px away: another

    from viewer.photo.frames import read_photo
    from viewer.photo.segmentation import find_person

    photo = read_photo(SKIER, [])
    person = find_person(photo, SKIER)
    alone = matting.automatic_matte(photo, person)  # a photo (or a shot's first frame): kept as found
    assert alone.held.any() and (alone.objects == alone.held).all()
    before = trimap.Carried(alone.alpha, np.ones(alone.alpha.shape, np.float32), np.zeros(alone.alpha.shape, bool))
    first = matting.automatic_matte(photo, person, before)  # found now, not the frame before: not kept yet
    assert not first.held.any() and first.objects.any() and first.record["held_px"] == 0
    again = matting.automatic_matte(photo, person, replace(before, objects=first.objects))  # found in both
    assert again.held.any() and (again.held == again.objects).all() and (again.objects == first.objects).all()
