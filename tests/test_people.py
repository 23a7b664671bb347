"""Synthetic people (viewer/data): seeded bodies, poses, outfits and their G-buffers, built with the
real anny body model (the first construction on a machine builds its cache: a minute or two)."""

from __future__ import annotations

import numpy as np
import pytest

from dataclasses import replace

from viewer.lab.data.geometry import subdivide, vertex_normals
from viewer.lab.data.humans import POSE_STYLES, build_body, fold, sample_phenotype, sample_pose
from viewer.lab.data.materials import SAMPLE_OUTFIT, classify, sample_outfit
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
    styles, skins, sleeves, legs, dresses, long_hair, saturations = set(), [], set(), set(), 0, 0, []
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
        long_hair += o.hair_length > 0
        c = np.array(o.top.color)
        saturations.append(1.0 - c.min() / max(c.max(), 1e-9))
    assert styles == set(POSE_STYLES)
    assert max(skins) > 3 * min(skins)  # light to dark skin
    assert len(sleeves) >= 4 and len(legs) >= 3 and 2 <= dresses <= 20
    assert 10 <= long_hair <= 35
    assert np.mean(np.array(saturations) > 0.8) > 0.3  # saturated cloth is common (linear RGB)


def test_long_hair_falls_down_the_back_and_folds_stay_on_cloth():
    neutral = dict(gender=0.5, age=0.8, muscle=0.5, weight=0.5, height=0.5, proportions=0.5)
    verts, faces, fields, heads, rest = build_body(neutral, {})
    short = classify(fields, heads, rest, SAMPLE_OUTFIT)["hair"]
    long = classify(fields, heads, rest, replace(SAMPLE_OUTFIT, hair_length=0.3))["hair"]
    assert (short <= long).all() and long.sum() > 1.5 * short.sum()
    added = long & ~short
    neck = heads["neck01"]
    ears_front = heads["head"][1] - 0.045  # classify's ears start 4.5 cm in front of the head's centre
    assert (rest[added, 1] >= ears_front).all()  # the ears, the back of the head and the back: never the face
    assert rest[added, 2].min() < neck[2] - 0.2  # well below the neck
    # folds: displacement along the normals of at most the amplitude, on cloth and hair only
    pos, f, at = subdivide(verts, faces, {"normal": vertex_normals(verts, faces), "fields": fields}, 1)
    n = at["normal"] / np.linalg.norm(at["normal"], axis=1, keepdims=True)
    outfit = replace(SAMPLE_OUTFIT, folds=0.005)
    moved, n2 = fold(pos, f, n, at["fields"], heads, rest, outfit, 1.0, 3)
    shift = np.linalg.norm(moved - pos, axis=1)
    regions = classify(at["fields"], heads, rest, outfit)
    assert shift.max() <= 0.005 + 1e-9 and shift[regions["shirt"]].mean() > 0.0005
    assert shift[regions["skin"] & (at["fields"][:, 5] > 0.5)].max() < 1e-9  # the face is not folded
    assert np.allclose(np.linalg.norm(n2, axis=1), 1.0)
    bent = np.degrees(np.arccos(np.clip((n2 * n).sum(1), -1, 1)))
    assert 2.0 < np.median(bent[regions["shirt"]]) < 30.0 and np.percentile(bent[regions["skin"] & (at["fields"][:, 5] > 0.5)], 90) < 1e-3  # (only the ring next to the hair turns)


def test_preview_draws_people_and_maps(tmp_path, capsys):
    from viewer.cli import main

    assert main(["dataset", "preview", "--out", str(tmp_path), "--count", "1"]) == 0
    import imageio.v3 as iio

    for name in ("dataset_people.png", "procedural_envmaps.png"):
        img = iio.imread(tmp_path / name)
        assert img.ndim == 3 and img.shape[0] > 200 and img[..., :3].std() > 20  # a picture, not a blank
    assert "wrote" in capsys.readouterr().out
    assert main(["dataset", "preview", "--out", str(tmp_path), "--count", "0"]) == 2
