"""The one person a clip relights (viewer.photo.person_track): chosen once (largest and most
central, or under a point), told from others by their colours and where they were, and no one
picked when they are gone (the clip then shows the new background, never a bystander)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from viewer.photo.person_track import MERGED, SAME, Part, PersonTrack, choose, distance, signature


def dressed(top: tuple, legs: tuple, size=(120, 60), seed=0) -> tuple[np.ndarray, np.ndarray]:
    """A figure of ``size`` (h, w): a top and trousers of these RGB colours, a little noise; its mask."""
    h, w = size
    rng = np.random.default_rng(seed)
    image = np.zeros((h, w, 3), np.float32)
    image[: h // 2] = top
    image[h // 2:] = legs
    image = np.clip(image + rng.normal(0, 6, image.shape), 0, 255).astype(np.uint8)
    return image, np.ones((h, w), bool)


def part(colours: tuple, box: tuple, seed=0) -> Part:
    image, mask = dressed(*colours, seed=seed)
    return Part(box, signature(image, mask, (0, 0, image.shape[1], image.shape[0])))


RED_JEANS = ((200, 30, 40), (40, 50, 110))
GREEN_KHAKI = ((40, 160, 60), (170, 150, 100))


def test_signatures_tell_the_same_clothes_from_others():
    a, b, c = part(RED_JEANS, (0, 0, 1, 1)), part(RED_JEANS, (0, 0, 1, 1), seed=1), part(GREEN_KHAKI, (0, 0, 1, 1))
    assert distance(a.signature, b.signature) < 0.1 < SAME < distance(a.signature, c.signature)
    assert abs(distance(a.signature, a.signature)) < 1e-6


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 255), st.integers(0, 255), st.integers(0, 255), st.integers(1, 200))
def test_distance_is_bounded_and_symmetric(r, g, b, seed):
    a = part(((r, g, b), (b, r, g)), (0, 0, 1, 1), seed=seed).signature
    other = part(RED_JEANS, (0, 0, 1, 1)).signature
    d = distance(a, other)
    assert 0.0 <= d <= 1.0 and abs(d - distance(other, a)) < 1e-6
    assert distance(a, np.zeros_like(a)) == 1.0  # nothing shared: unlike


def test_choose_the_largest_and_most_central_or_the_one_pointed_at():
    centre = part(RED_JEANS, (0.4, 0.2, 0.2, 0.6))
    edge_big = part(GREEN_KHAKI, (0.0, 0.1, 0.2, 0.65))  # a little taller, at the edge
    far = part(GREEN_KHAKI, (0.7, 0.5, 0.05, 0.15))
    assert choose([edge_big, centre, far]) == 1
    assert choose([edge_big, centre, far], point=(0.72, 0.6)) == 2  # inside its box
    assert choose([edge_big, centre, far], point=(0.9, 0.95)) == 2  # the nearest box
    assert choose([]) is None


def test_followed_by_colour_and_place_never_a_stranger():
    person = part(RED_JEANS, (0.4, 0.2, 0.2, 0.6))
    track = PersonTrack({"box": list(person.box), "signature": person.signature.tolist(), "frame": 0})
    stranger_in_front = part(GREEN_KHAKI, (0.35, 0.1, 0.3, 0.8))
    track.at(1)
    # the person moved, a larger stranger stepped in: the person
    moved = part(RED_JEANS, (0.55, 0.2, 0.2, 0.6), seed=3)
    assert track.pick([stranger_in_front, moved]) == 1
    track.seen(moved, alone=True)
    # the person gone, the stranger where they were: no one (not the stranger)
    track.at(2)
    assert track.pick([part(GREEN_KHAKI, (0.55, 0.2, 0.2, 0.6))]) is None
    # back after a long gap, anywhere: found by their colours
    track.at(200)
    assert track.pick([stranger_in_front, part(RED_JEANS, (0.05, 0.3, 0.15, 0.5), seed=5)]) == 1
    # touching someone (one part, colours mixed) where they just were: still them
    track.seen(part(RED_JEANS, (0.05, 0.3, 0.15, 0.5)), alone=True)
    track.at(201)
    image_a, _ = dressed(*RED_JEANS)
    image_b, _ = dressed(*GREEN_KHAKI)
    pair = np.concatenate([image_a, image_b], axis=1)
    mixed = Part((0.05, 0.3, 0.3, 0.5), signature(pair, np.ones(pair.shape[:2], bool), (0, 0, pair.shape[1], pair.shape[0])))
    assert SAME < track.unlike(mixed) <= MERGED
    assert track.pick([mixed]) == 0
    # ... but the same mixed part far from where they were is not taken for them
    track.at(202)
    far_mixed = Part((0.8, 0.3, 0.15, 0.5), mixed.signature)
    assert track.pick([far_mixed]) is None
