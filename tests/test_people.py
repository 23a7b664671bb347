"""Synthetic people (viewer/data): seeded bodies, poses, outfits and their G-buffers, built with the
real anny body model (the first construction on a machine builds its cache: a minute or two)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from viewer.lab.data.geometry import subdivide, vertex_normals
from viewer.lab.data.humans import POSE_STYLES, build_body, fold, sample_phenotype, sample_pose
from viewer.lab.data.materials import SAMPLE_OUTFIT, classify, sample_outfit
from viewer.lab.data.people import make_person
from viewer.scene.resampling import depth_normal_angle


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
    assert 2.0 < np.median(bent[regions["shirt"]]) < 30.0 and np.percentile(bent[regions["skin"] & (at["fields"][:, 5] > 0.5)],
                                                                            90) < 1e-3  # (only the ring next to the hair turns)


def test_preview_draws_people_and_maps(tmp_path, capsys):
    from viewer.cli.main import main

    assert main(["dataset", "preview", "--out", str(tmp_path), "--count", "1"]) == 0
    import imageio.v3 as iio

    for name in ("dataset_people.png", "procedural_envmaps.png"):
        img = iio.imread(tmp_path / name)
        assert img.ndim == 3 and img.shape[0] > 200 and img[..., :3].std() > 20  # a picture, not a blank
    assert "wrote" in capsys.readouterr().out
    assert main(["dataset", "preview", "--out", str(tmp_path), "--count", "0"]) == 2


def test_sitting_and_accessories_leave_the_rest_of_a_person_as_it_was():
    from viewer.lab.data.people import person_draws

    styles, bags = [], []
    for seed in range(200):
        phenotype, style, pose, outfit, turn, fill = person_draws(seed)
        rng = np.random.default_rng([seed, 0xB0D1])  # the first stream, as before accessories existed
        assert phenotype == sample_phenotype(rng)
        first_style, first_pose = sample_pose(rng)
        assert replace(outfit, accessories=SAMPLE_OUTFIT.accessories) == sample_outfit(rng)
        assert style == first_style or style == "sitting"
        styles.append(style)
        bags.append(outfit.accessories.bag)
        if style == "sitting":
            assert outfit.accessories.bag is None  # no bag in the lap
    assert 10 <= styles.count("sitting") <= 35
    assert 15 <= bags.count("crossbody") <= 50 and 8 <= bags.count("backpack") <= 35


def test_a_sitting_person_sits():
    from viewer.lab.data.people import person_draws

    seed = next(s for s in range(100) if person_draws(s)[1] == "sitting")
    phenotype, _, pose, *_ = person_draws(seed)
    verts, faces, fields, heads, rest = build_body(phenotype, pose)
    for side, sign in (("L", 1.0), ("R", -1.0)):
        foot = verts[(fields[:, 7] > 0.5) & (sign * rest[:, 0] > 0)].mean(axis=0)
        knee = verts[np.argmin(np.linalg.norm(rest - heads[f"lowerleg01.{side}"], axis=1))]
        hip = verts[np.argmin(np.linalg.norm(rest - heads[f"upperleg01.{side}"], axis=1))]
        assert knee[1] < hip[1] - 0.3  # the thigh reaches forward (anny's -y) ...
        assert abs(knee[2] - hip[2]) < 0.2  # ... about level
        assert foot[2] < knee[2] - 0.3 and abs(foot[1] - knee[1]) < 0.25  # the shin hangs down


def test_a_bag_hangs_on_the_body_and_its_strap_crosses_the_shirt(people):
    from viewer.lab.data.accessories import bag_mesh
    from viewer.lab.data.geometry import signed_volume

    p = people[1]  # seed 1 carries a crossbody bag
    a = p.outfit.accessories
    assert a.bag == "crossbody"
    bag_verts = 2562  # the rounded box: an icosphere of level 4
    bag = p.vertices[-bag_verts:]
    body = p.vertices[:-bag_verts]
    assert signed_volume(bag.astype(np.float64), p.faces[-5120:] - (len(p.vertices) - bag_verts)) > 0.0  # outward
    # on the body: its nearest body vertex within a few centimetres, its centre outside the body's hull at the hip
    gap = np.min(np.linalg.norm(body[::7, None, :] - bag[None, ::11, :], axis=-1))
    height = np.ptp(body[:, 1])
    assert gap < 0.03 * height
    assert np.ptp(bag[:, 1]) == pytest.approx(0.18 / 1.7 * height, rel=0.35)  # 18 cm high on a person of ~1.7 m
    # the bag and its strap show in the G-buffers in the bag's colour
    colour = np.array(a.bag_color)
    near = np.linalg.norm(p.scene.albedo - colour, axis=-1) < 0.08
    assert (near & p.scene.mask).sum() >= 10
    assert bag_mesh(replace(a, bag=None), p.vertices, p.normals, np.zeros((len(p.vertices), 8)), {}, 1.0) is None


def test_worn_accessories_are_bands_where_they_belong():
    from viewer.lab.data.materials import Accessories

    neutral = dict(gender=0.5, age=0.8, muscle=0.5, weight=0.5, height=0.5, proportions=0.5)
    verts, faces, fields, heads, rest = build_body(neutral, {})
    _, _, at = subdivide(verts, faces, {"fields": fields}, 2)  # as fine as the people's meshes
    fields = at["fields"]
    worn = replace(SAMPLE_OUTFIT, accessories=Accessories(bag="backpack", watch=(0.6, 0.6, 0.6), necklace=(0.8, 0.55, 0.22),
                                                          cap=(0.1, 0.1, 0.5)))
    bare, r = classify(fields, heads, rest, SAMPLE_OUTFIT), classify(fields, heads, rest, worn)
    for name in ("strap", "watch", "necklace", "cap"):
        assert r[name].sum() > 20 and not bare[name].any()
        for other in ("skin", "hair", "shirt"):
            assert not (r[name] & r[other]).any()
    p = fields[:, 0:3]
    assert (p[r["watch"], 0] > heads["lowerarm01.L"][0]).all()  # the left forearm, past the elbow
    assert np.linalg.norm(p[r["watch"]] - heads["wrist.L"], axis=1).max() < 0.08
    assert (np.abs(p[r["necklace"], 2] - heads["neck01"][2]) < 0.12).all()
    assert (p[r["cap"], 2] > heads["eye.L"][2]).all() and (bare["hair"] & r["cap"]).sum() > 0.5 * r["cap"].sum()
    assert (p[r["strap"], 2] > heads["spine01"][2] - 0.1).all()  # backpack straps: over the shoulders
