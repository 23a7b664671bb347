"""Synthetic people (viewer/data): seeded bodies, poses, outfits and their G-buffers, built with the
real anny body model (the first construction on a machine builds its cache: a minute or two)."""

from __future__ import annotations

import numpy as np
import pytest

from viewer.lab.data.humans import POSE_STYLES, sample_phenotype, sample_pose
from viewer.lab.data.materials import sample_outfit
from viewer.lab.data.people import make_person
from viewer.scene_ops import depth_normal_angle


@pytest.fixture(scope="module")
def people():
    return [make_person(seed, 96) for seed in (0, 1)] + [make_person(0, 96)]


def test_same_seed_same_person_bit_for_bit(people):
    a, b, again = people
    for name in ("albedo", "specular", "roughness", "normal", "depth", "mask"):
        assert np.array_equal(getattr(a.scene, name), getattr(again.scene, name))
        assert not np.array_equal(getattr(a.scene, name), getattr(b.scene, name))
    assert np.array_equal(a.vertices, again.vertices) and a.meta() == again.meta()


def test_g_buffers_are_a_valid_full_body_bundle(people):
    for p in people[:2]:
        s = p.scene
        rows = np.nonzero(s.mask.any(axis=1))[0]
        assert 0.75 <= (rows.max() - rows.min() + 1) / s.height <= 0.95  # a full body, head to feet
        assert 3.0 < s.depth[s.mask].min() and s.depth[s.mask].max() < 5.0
        assert 0.0 <= s.albedo.min() and s.albedo.max() <= 1.0 and (s.roughness[s.mask] > 0).all()
        # the depth reprojects to the normals
        angle, valid = depth_normal_angle(s)
        assert valid.sum() > 300 and np.median(angle[valid]) < 10.0


def test_samplers_cover_their_ranges():
    styles, skins, sleeves, legs, dresses = set(), [], set(), set(), 0
    for seed in range(60):
        rng = np.random.default_rng(seed)
        ph = sample_phenotype(rng)
        assert all(0.0 <= v <= 1.0 for v in ph.values())
        style, pose = sample_pose(rng)
        styles.add(style)
        assert all(np.all(np.abs(v) <= 2.0) for v in pose.values())  # radians: no wild joints
        o = sample_outfit(rng)
        skins.append(np.mean(o.skin))
        sleeves.add(o.sleeve)
        legs.add(o.leg)
        dresses += o.top == o.bottom and o.leg < 1.0 and o.belt is None
    assert styles == set(POSE_STYLES)
    assert max(skins) > 3 * min(skins)  # light to dark skin
    assert len(sleeves) >= 4 and len(legs) >= 3 and 2 <= dresses <= 20
