"""The person's true matte (viewer/photo/matting.py) on real photos and on known answers: the trimap's
band holds the gaps between limbs, the matte meets the hand-made masks, the old background leaves
the person's colours, a plain backdrop seen between the limbs is cut out, hair stays soft, and a
mask file still wins."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SHARED_DATA

from viewer.files.imageio import srgb_to_linear
from viewer.lab.bench.metrics import bleed, kept_backdrop, on_backdrop, spill_cut
from viewer.photo import matting, trimap
from viewer.photo.frames import output_frame, read_mask, read_photo
from viewer.photo.pose_masks import head_mask, person_height
from viewer.photo.segmentation import find_person
from viewer.resize import resize

PHOTOS = SHARED_DATA / "photos"
STEMS = ("unsplash-1507274733827", "unsplash-1535323700481")


def _frame(stem):
    """The photo at its output frame (at most 2048 px) and the hand-made mask there (evaluation only)."""
    photo = read_photo(PHOTOS / f"{stem}.jpg", [])
    h, w = photo.shape[:2]
    frame = output_frame((w, h))
    hand = np.clip(resize(read_mask(PHOTOS / f"{stem}.mask.png", (h, w), []), frame), 0, 1)
    return resize(photo, frame), hand


@pytest.fixture(scope="module", params=STEMS)
def matted(request):
    photo, hand = _frame(request.param)
    person = find_person(photo, request.param)
    return photo, hand, person, matting.automatic_matte(photo, person)


def test_the_trimaps_band_holds_the_gaps_between_limbs(matted):
    """Background the segmentation filled (between an arm and the body, between the legs) is never
    the person for sure: the colours decide it."""
    photo, hand, person, _ = matted
    tri = trimap.trimap(person.segmentation, person.landmarks)
    filled = (person.segmentation > 0.5) & (hand < 0.5)  # the segmentation's background mistaken for the person
    inside, _ = trimap.distances(hand > 0.5)
    _, outside = trimap.distances(hand > 0.5)
    far = filled & (outside > 6)  # more than a soft edge away from the person's true outline
    assert far.sum() > 500  # the photos do have such gaps
    assert (tri.sure_person & far).sum() < 0.02 * far.sum()
    assert not (tri.sure_background & (hand > 0.5) & (inside > 6)).any()


def test_the_matte_meets_the_hand_made_masks(matted):
    photo, hand, _, matte = matted
    assert matte.alpha.shape == hand.shape and matte.alpha.dtype == np.float32
    assert np.isfinite(matte.alpha).all() and 0 <= matte.alpha.min() and matte.alpha.max() <= 1
    scores = spill_cut(matte.alpha, hand)
    before = spill_cut((person_seg := find_person(photo).segmentation > 0.5).astype(np.float32), hand)
    assert scores["spill"] <= 0.2 and scores["cut"] <= 0.16, scores  # docs/photos.md: targets 0.2 and 0.15
    assert scores["spill"] < 0.5 * before["spill"]  # the segmentation alone spills 0.40-0.48 px
    assert person_seg.any()


def test_the_old_background_leaves_the_persons_colours(matted):
    photo, _, _, matte = matted
    linear = srgb_to_linear(photo.astype(np.float32) / 255.0)
    soft = (matte.alpha > 0.05) & (matte.alpha < 0.95)
    assert soft.sum() > 1000  # a soft edge, not a cut
    assert np.isfinite(matte.foreground).all() and matte.foreground.min() >= 0
    depth, _ = trimap.distances(matte.alpha >= matting.OPAQUE)
    deep = depth > max(matting.MIN_EDGE, matting.EDGE * person_height(matte.alpha > 0.5))
    assert np.array_equal(matte.foreground[deep], linear[deep])  # the photo's own, half a band inside
    assert np.array_equal(matte.foreground[matte.alpha <= 0], linear[matte.alpha <= 0])
    assert bleed(matte.foreground, matte.alpha, linear) <= 0.05
    assert bleed(linear, matte.alpha, linear) > 0.08  # the photo's own colours at the same edge bleed


@pytest.mark.parametrize("stem", STEMS)
def test_a_plain_backdrop_between_the_limbs_is_cut_out(stem):
    """The person on a flat pink backdrop (the pink between the arm and the body, between the
    legs): almost no pink is kept as the person."""
    photo, hand = _frame(stem)
    pink = on_backdrop(photo, hand)
    seg_only = (find_person(pink).segmentation > 0.5).astype(np.float32)
    matte = matting.automatic_matte(pink, find_person(pink))
    assert kept_backdrop(matte.alpha, pink, hand) <= 0.05
    assert kept_backdrop(seg_only, pink, hand) > 0.3  # what the segmentation alone keeps


def test_foreground_colours_recover_a_known_composite():
    """I = a F + (1 - a) B with a smooth F and B and a soft edge: F comes back where the edge is
    soft, the image's colour inside the opaque person (half a soft band in)."""
    h, w = 64, 96
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    alpha = np.clip((xx - 40) / 16, 0, 1)
    fg = np.stack([0.8 - 0.002 * yy, 0.3 + 0 * xx, 0.2 + 0.001 * xx], -1)
    bg = np.stack([0.1 + 0 * xx, 0.6 + 0.002 * yy, 0.9 + 0 * xx], -1)
    image = alpha[..., None] * fg + (1 - alpha[..., None]) * bg
    out = matting.foreground_colours(image, alpha, half_width=2.0)
    soft = (alpha > 0.2) & (alpha < 1)
    assert np.abs(out[soft] - fg[soft]).mean() < 0.05
    assert np.abs(image[soft] - fg[soft]).mean() > 0.15  # the image's colour there is mixed
    deep = trimap.distances(alpha >= matting.OPAQUE)[0] > 2.0  # half a band (half_width) inside
    assert np.array_equal(out[deep], image[deep].astype(np.float32))
    assert np.abs(out[alpha >= 1] - fg[alpha >= 1]).mean() < 0.02


def test_a_dark_person_on_a_bright_background_keeps_its_colour_to_the_edge():
    """A navy coat against a pale street, its edge blurred by the lens (mixed in linear light, as a
    camera mixes it), a binary mask softened by the closed-form edge: the matte's colours at the soft
    edge stay navy (not black, not the street's grey), and so does the edge's bleed."""
    import cv2

    h, w = 160, 160
    person = np.zeros((h, w), bool)
    cv2.circle(person.view(np.uint8), (80, 80), 50, 1, -1)
    navy, street = np.array([0.012, 0.018, 0.06]), np.array([0.45, 0.47, 0.46])
    rng = np.random.default_rng(1)
    linear = np.where(person[..., None], navy, street) * (1 + 0.05 * rng.standard_normal((h, w, 1)))
    linear = cv2.GaussianBlur(linear.astype(np.float32), (0, 0), 1.2)
    photo = np.clip(np.round(255 * (np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.maximum(linear, 0) ** (1 / 2.4) - 0.055))), 0,
                    255).astype(np.uint8)
    matte = matting.mask_matte(photo, person.astype(np.float32))
    soft = (matte.alpha > 0.3) & (matte.alpha < matting.OPAQUE)
    assert soft.sum() > 100
    f = matte.foreground[soft]
    assert 0.6 < np.median(f.sum(-1)) / navy.sum() < 1.5  # neither black nor grey (before: 1.77)
    chroma = f / np.maximum(f.sum(-1, keepdims=True), 1e-9)
    to_navy = np.linalg.norm(chroma - navy / navy.sum(), axis=-1)
    to_street = np.linalg.norm(chroma - street / street.sum(), axis=-1)
    assert (to_navy < to_street).mean() > 0.95  # before: 0.71
    # what bleed is left is the lens blur reaching past the soft edge (alpha 1, the photo's colour)
    assert bleed(matte.foreground, matte.alpha, srgb_to_linear(photo.astype(np.float32) / 255)) < 0.2  # before: 0.24


def test_hair_stays_semi_transparent():
    """The street photo's long hair against the shop: the matte's soft edge runs along it."""
    photo, hand = _frame("unsplash-1535323700481")
    person = find_person(photo)
    matte = matting.automatic_matte(photo, person)
    h, w = hand.shape
    x, y = person.landmarks[8]  # the right ear: the hair falls beside and below it
    box = (slice(int(y * h), int(y * h) + h // 6), slice(int(x * w) - w // 40, int(x * w) + w // 25))
    a = matte.alpha[box]
    assert ((a > 0.05) & (a < 0.95)).mean() > 0.01


def test_a_mask_file_wins():
    photo, hand = _frame("unsplash-1535323700481")
    soft = matting.mask_matte(photo, hand)  # the hand-made mask is soft at its edge: used as it is
    assert np.array_equal(soft.alpha, hand.astype(np.float32))
    binary = (hand > 0.5).astype(np.float32)
    hard = matting.mask_matte(photo, binary)  # a binary one is the core: its outline is softened
    inside, outside = trimap.distances(binary > 0.5)
    half = matting.EDGE * person_height(binary > 0.5)
    assert (hard.alpha[inside > half + 1] == 1).all() and (hard.alpha[outside > half + 1] == 0).all()
    assert ((hard.alpha > 0.05) & (hard.alpha < 0.95)).sum() > 1000
    assert spill_cut(hard.alpha, hand)["spill"] < 0.05 and spill_cut(hard.alpha, hand)["cut"] < 0.05


def test_nothing_held_is_nothing_added(matted):
    """Neither shared photo's person holds anything apart from her clothes: the held objects'
    search (viewer/photo/held_objects.py) adds nothing to the decided outline."""
    _, _, _, matte = matted
    assert matte.record["held_px"] <= 0.001 * int((matte.alpha > 0.5).sum())


def test_a_clips_frame_before_steadies_where_the_outline_is_decided():
    """Where colour does not tell the person from the background (the same grey), the band is decided
    by the segmentation; a clip's frame before, carried along the flow, moves the decision towards
    its own outline where the flow holds (TEMPORAL nats) inside the segmentation's outline, and nowhere
    the flow fails. Beyond the segmentation's outline, where this frame's own evidence is the
    background's, it pulls nothing in: a frame before
    4 px larger than the segmentation grows the person there by under a quarter of a pixel (what the
    outline's smoothness drags along; before, by 0.74 px, a ring of the old background handed on)."""
    import cv2

    from viewer.photo.colour_models import colour_models
    from viewer.photo.matting import decide_band
    from viewer.photo.trimap import Carried, trimap

    h = w = 400
    seg = np.zeros((h, w), np.float32)
    cv2.circle(seg, (200, 200), 120, 1.0, -1)
    image = np.full((h, w, 3), 0.5, np.float32)
    image += np.random.default_rng(0).normal(0, 0.01, image.shape).astype(np.float32)
    tri = trimap(seg, {})
    models = colour_models(image, tri.samples, tri.sure_background, ~tri.sure_background, 0.03 * tri.height)

    def disk(r):
        d = np.zeros((h, w), np.float32)
        cv2.circle(d, (200, 200), r, 1.0, -1)
        return d

    def beyond(person):  # the person outside the segmentation's outline, pixels per outline pixel
        return (person & (seg <= 0.5)).sum() / (2 * np.pi * 120)

    alone = decide_band(image, tri, models)
    bigger = decide_band(image, tri, models, Carried(disk(124), np.ones((h, w), np.float32)))
    smaller = decide_band(image, tri, models, Carried(disk(116), np.ones((h, w), np.float32))).sum()
    unheld = decide_band(image, tri, models, Carried(disk(124), np.zeros((h, w), np.float32))).sum()
    assert smaller < alone.sum() < bigger.sum()
    assert beyond(bigger) - beyond(alone) < 0.25
    assert unheld == alone.sum()


def test_the_outline_is_decided_around_the_person():
    """A person a fifth of a 1280x720 frame is decided in a window around them (their box grown by a
    quarter of their height), the rest of the frame being sure background: the same outline, holes
    and gaps as over the whole frame to within a few pixels, in well under half the time's pixels.
    A person taller than the solve height is decided over the whole frame, as before."""
    from viewer.resources import asset_dir

    photo = read_photo(asset_dir() / "photos/underpass.jpg", [])
    scale = 400 / photo.shape[0]
    small = resize(photo, (round(photo.shape[1] * scale), 400))
    frame = np.pad(small, ((200, 720 - 200 - small.shape[0]), (500, 1280 - 500 - small.shape[1]), (0, 0)), mode="edge")
    person = find_person(frame, "small person")
    window = matting.solve_window(person.segmentation)
    assert window is not None
    rows, cols = window
    assert (rows.stop - rows.start) * (cols.stop - cols.start) < 0.5 * 1280 * 720
    cropped, whole = matting.decided_outline(frame, person), matting._decided_outline(frame, person)
    assert cropped[3] == whole[3]
    people = int(whole[0].sum())
    for a, b in zip(cropped[:3], whole[:3]):
        assert int((a != b).sum()) <= 1e-3 * people
    outside = np.ones(frame.shape[:2], bool)
    outside[window] = False
    assert not cropped[0][outside].any()
    tall = resize(photo, (round(photo.shape[1] * 900 / photo.shape[0]), 900))
    assert matting.solve_window(find_person(tall, "tall person").segmentation) is None


def test_dark_hair_against_a_dark_background_is_kept():
    """A man's black hair against a dark sign (a frame of the shared taiji clip): the colour cut called it
    background and the relit man was bald. The crown, the ellipse of the head above the brows the pose's
    face gives (pose_masks.head_mask), is the person for sure within the segmentation: the matte's top at the
    head is the segmentation's, not 15 px under it. A face without a mouth gives no crown."""
    import av

    with av.open(str(SHARED_DATA / "videos" / "hybrik_taiji.mp4")) as clip:
        photo = next(f.to_ndarray(format="rgb24") for i, f in enumerate(clip.decode(video=0)) if i == 6)
    person = find_person(photo, "taiji")
    alpha = matting.automatic_matte(photo, person).alpha
    h, w = alpha.shape
    eyes = 0.5 * (np.array(person.landmarks[2]) + np.array(person.landmarks[5])) * (w, h)
    columns = slice(int(eyes[0]) - 15, int(eyes[0]) + 15)
    top_seg = np.flatnonzero((person.segmentation[:, columns] > 0.5).any(axis=1))[0]
    top_matte = np.flatnonzero((alpha[:, columns] > 0.5).any(axis=1))[0]
    assert top_matte <= top_seg + 5, (top_matte, top_seg)
    crown = head_mask(person.landmarks, (w, h))
    assert crown is not None and crown.any() and not crown[int(eyes[1]) + 8:].any()  # above the eyes (the face a little tilted)
    assert head_mask({k: v for k, v in person.landmarks.items() if k not in (9, 10)}, (w, h)) is None
