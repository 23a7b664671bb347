"""How shiny each region may be (viewer/photo/gloss.py): skin, told by the face's colour, keeps the
network's roughness; dark cloth and the rest become matte; without a face nothing changes."""

from __future__ import annotations

import numpy as np
from conftest import SHARED_DATA

from viewer.files.imageio import srgb_to_linear
from viewer.photo import gloss
from viewer.photo.frames import read_photo
from viewer.photo.segmentation import find_person
from viewer.resize import resize


def test_skin_is_told_from_cloth_by_the_faces_colour():
    photo = resize(read_photo(SHARED_DATA / "photos" / "unsplash-1535323700481.jpg", []), (975, 651))
    person = find_person(photo)
    alpha = person.segmentation
    linear = srgb_to_linear(photo.astype(np.float32) / 255.0)
    skin = gloss.skin(linear, alpha, person.landmarks)
    assert skin is not None and skin.shape == alpha.shape and 0 <= skin.min() and skin.max() <= 1
    h, w = alpha.shape
    nose = person.landmarks[0]
    face = skin[int(nose[1] * h) - 3:int(nose[1] * h) + 4, int(nose[0] * w) - 3:int(nose[0] * w) + 4]
    assert face.mean() > 0.4  # the nose (its nostrils are dark)
    shin = [np.array(person.landmarks[26]) * (1 - t) + np.array(person.landmarks[28]) * t for t in np.linspace(0.2, 0.6, 9)]
    assert np.median([skin[int(y * h), int(x * w)] for x, y in shin]) > 0.3  # the bare leg below the dress
    dark = (linear @ np.array([0.2126, 0.7152, 0.0722]) < 0.02) & (alpha > 0.5)  # the black scarf, coat and bag
    assert dark.sum() > 1000 and skin[dark].max() == 0.0
    assert (skin[alpha == 0] == 0).all()
    assert gloss.skin(linear, alpha, {}) is None  # no face: no model


def test_what_is_not_skin_becomes_matte():
    rough = np.full((4, 4), 0.5, np.float32)
    share = np.zeros((4, 4), np.float32)
    share[:2] = 1.0
    out = gloss.matte_roughness(rough, share)
    assert np.allclose(out[:2], 0.5) and np.allclose(out[2:], gloss.MATTE_ROUGHNESS)
    rough[0, 0] = 0.95
    assert gloss.matte_roughness(rough, share)[0, 0] == np.float32(0.95)  # never made glossier
    assert gloss.matte_roughness(rough, None) is rough
