"""The GL engine on a real EGL context (Mesa llvmpipe here): shading, shadows, caching, skipping."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import render_by_units

from viewer.gl import Engine, EngineOptions
from viewer.gl.prefilter import blur_plan
from viewer.lab.scenes import plane_and_box
from viewer.scene.area_lights import AreaLights
from viewer.scene.look import Look


def relook(eng, **changes):
    """The engine's look with ``changes`` (the display fields, the terms shown)."""
    eng.set_look(eng.look.replace(**changes))


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return (v / np.linalg.norm(v, axis=-1, keepdims=True)).astype(np.float32)


def numpy_shading(n, l, specular, roughness):
    """Direct evaluation of docs/conventions.md's BRDF (per unit intensity)."""
    v = np.array([0.0, 0.0, 1.0])
    nl, nv = float(n @ l), float(n @ v)
    diff = max(nl, 0.0) / np.pi
    if nl <= 0 or nv <= 0 or specular <= 0:
        return diff, 0.0
    h = (l + v) / np.linalg.norm(l + v)
    nh, lh = float(n @ h), float(l @ h)
    a = max(roughness**2, 1e-3)
    a2 = a * a
    f0 = 0.08 * specular
    f = f0 + (1 - f0) * (1 - lh) ** 5
    d = a2 / (np.pi * (nh * nh * (a2 - 1) + 1) ** 2)
    g = 1 / (nl + np.sqrt(a2 + nl * nl - a2 * nl * nl)) / (nv + np.sqrt(a2 + nv * nv - a2 * nv * nv))
    return diff, nl * f * d * g


@pytest.fixture
def scene():
    return plane_and_box(96)


def make_engine(ctx, scene, **kw):
    kw.setdefault("shadow_resolution", 256)
    kw.setdefault("shadow_step", 1)
    return Engine(ctx, scene, EngineOptions(**kw))


@pytest.mark.parametrize("roughness", [0.0, 0.3, 1.0])
def test_shading_matches_brdf_formula(ctx, roughness):
    sc = plane_and_box(32, box=False, specular=0.8, roughness=roughness)
    l = unit([0.2, 0.3, 1.0])
    eng = make_engine(ctx, sc)
    eng.set_lights(AreaLights(l[None], [0.0], [[1, 1, 1]]))
    eng.render()
    out = eng.output.read_light(0)
    diff, spec = numpy_shading(np.array([0, 0, 1.0]), l.astype(np.float64), 0.8, roughness)
    np.testing.assert_allclose(out["diffuse"], diff, rtol=1e-5)
    np.testing.assert_allclose(out["specular"], spec, rtol=1e-4)
    hdr = eng.output.read_hdr()
    np.testing.assert_allclose(hdr, 0.5 * diff + spec, rtol=1e-4)
    eng.release()


def test_box_casts_shadow_in_the_right_place(ctx, scene):
    l = unit([0.3, 0.4, 1.0])
    eng = make_engine(ctx, scene)
    eng.set_lights(AreaLights(l[None], [0.0], [[1, 1, 1]]))
    eng.render()
    hard = eng.output.read_light(0)["visibility_hard"]
    # Expected shadow: plane points whose ray towards the light passes the box square at z = -3.6.
    pts = scene.points()
    t = (-3.6 - pts[..., 2]) / l[2]
    hit = pts[..., :2] + t[..., None] * l[:2]
    on_plane = scene.depth > 3.9
    expected = on_plane & (np.abs(hit[..., 0]) < 0.18) & (np.abs(hit[..., 1]) < 0.18)
    assert expected.sum() > 30
    shadow = hard < 0.5
    disagree = (shadow != expected).sum()
    boundary = expected.sum() ** 0.5 * 4  # a one-pixel band around the shadow's outline
    assert disagree <= boundary, (disagree, boundary)
    # no self-shadowing acne on the lit plane or the box face
    assert hard[~expected].mean() > 0.995
    eng.release()


def test_grazing_light_has_no_acne(ctx):
    sc = plane_and_box(64, box=False)
    for elevation in (2.0, 5.0, 10.0):
        e = np.radians(elevation)
        l = unit([np.cos(e), 0.0, np.sin(e)])
        eng = make_engine(ctx, sc)
        eng.set_lights(AreaLights(l[None], [0.0], [[1, 1, 1]]))
        eng.render()
        out = eng.output.read_light(0)
        assert out["visibility_hard"].mean() > 0.99, elevation
        assert out["visibility_soft"].mean() > 0.99, elevation
        eng.release()


def test_sigma_zero_converges_to_hard(ctx, scene):
    l = unit([0.3, 0.4, 1.0])
    diffs = []
    for sigma in (2.0, 1.0, 0.5, 0.25, 0.06):
        eng = make_engine(ctx, scene, hard_sigma=0.0)
        eng.set_lights(AreaLights(l[None], [sigma], [[1, 1, 1]]))
        eng.render()
        out = eng.output.read_light(0)
        diffs.append(float(np.abs(out["visibility_soft"] - out["visibility_hard"]).mean()))
        eng.release()
    assert all(a >= b - 1e-4 for a, b in zip(diffs, diffs[1:])), diffs
    assert diffs[-1] < 2e-3, diffs


def test_soft_filter_skip_matches_full_computation(ctx, scene):
    """Below hard_sigma the engine uses the hard test for soft visibility; computing the CSM at that
    sigma instead differs by less than the stated tolerance."""
    l = unit([0.3, 0.4, 1.0])
    sigma = EngineOptions().hard_sigma * 0.99
    out = {}
    for hs in (EngineOptions().hard_sigma, 0.0):
        eng = make_engine(ctx, scene, hard_sigma=hs, soft="csm")
        eng.set_lights(AreaLights(l[None], [sigma], [[1, 1, 1]]))
        eng.render()
        out[hs] = (eng.output.read_hdr(), eng.kit.counters["prefilter"])
        eng.release()
    skipped, full = out[EngineOptions().hard_sigma], out[0.0]
    assert skipped[1] == 0 and full[1] == 1
    assert np.abs(skipped[0] - full[0]).mean() < 2e-3 * full[0].mean()


def test_larger_sigma_gives_smoother_shadows(ctx, scene):
    l = unit([0.3, 0.4, 1.0])
    tv = []
    for sigma in (0.5, 2.0, 6.0, 15.0):
        eng = make_engine(ctx, scene)
        eng.set_lights(AreaLights(l[None], [sigma], [[1, 1, 1]]))
        eng.render()
        v = eng.output.read_light(0)["visibility_soft"]
        tv.append(float((np.diff(v, axis=0) ** 2).sum() + (np.diff(v, axis=1) ** 2).sum()))  # gradient energy
        assert 0.0 <= v.min() and v.max() <= 1.0
        eng.release()
    assert all(a > b for a, b in zip(tv, tv[1:])), tv


def test_pyramid_prefilter_close_to_exact(ctx, scene):
    l = unit([0.3, 0.4, 1.0])
    for sigma in (1.0, 4.0, 12.0, 30.0):
        vis = {}
        for method in ("pyramid", "exact"):
            eng = make_engine(ctx, scene, prefilter=method)
            eng.set_lights(AreaLights(l[None], [sigma], [[1, 1, 1]]))
            eng.render()
            vis[method] = eng.output.read_light(0)["visibility_soft"]
            eng.release()
        err = np.abs(vis["pyramid"] - vis["exact"])
        assert err.mean() < 0.01 and err.max() < 0.15, (sigma, err.mean(), err.max())


def test_pyramid_kernel_bounded():
    radii = [blur_plan(s, 512, "pyramid").radius for s in np.linspace(0, 400, 200)]
    assert max(radii) <= 6
    assert blur_plan(100, 512, "exact").radius == 300


def test_cache_rules(ctx, scene):
    lights = AreaLights(unit([[0.3, 0.4, 1.0], [-0.5, 0.2, 1.0], [0.1, 0.9, 0.5]]), [3.0, 6.0, 0.0],
                        [[1, 1, 1], [0.5, 0.4, 0.3], [0.2, 0.2, 0.2]])
    eng = make_engine(ctx, scene, soft="csm")
    eng.set_lights(lights)
    eng.render()
    c = dict(eng.kit.counters)
    assert c["shadow_map"] == 3 and c["prefilter"] == 2 and c["light_pass"] == 1  # light 3 is hard; one pass per 4 lights
    before = eng.output.read_hdr()

    def delta(action):
        start = dict(eng.kit.counters)
        action()
        eng.render()
        return {k: v - start.get(k, 0) for k, v in eng.kit.counters.items() if v - start.get(k, 0)}

    assert delta(lambda: eng.set_lights(lights.with_sigma(1, 9.0))) == {"csm_basis": 1, "prefilter": 1, "light_pass": 1, "composite": 1,
                                                                        "display": 1}
    assert delta(lambda: eng.set_lights(lights.with_sigma(1, 9.0).scaled(2.0))) == {"composite": 1, "display": 1}
    assert delta(lambda: relook(eng, exposure=1.0)) == {"display": 1}
    assert delta(lambda: relook(eng, exposure=1.0, yaw=0.0)) == {}  # unchanged: nothing redone
    assert delta(lambda: eng.render()) == {}
    rotated = lights.with_sigma(1, 9.0).scaled(2.0).rotated(20.0)
    assert delta(lambda: eng.set_lights(rotated)) == {"shadow_map": 3, "csm_basis": 2, "prefilter": 2, "light_pass": 1, "composite": 1,
                                                      "display": 1}
    # going back reproduces the first frame exactly (nothing stale survives in the cache)
    eng.set_lights(lights)
    eng.render()
    np.testing.assert_array_equal(eng.output.read_hdr(), before)
    eng.release()


def test_lights_that_contribute_nothing_are_skipped(ctx, scene):
    base = AreaLights(unit([[0.3, 0.4, 1.0], [0.0, 0.0, -1.0], [0.5, 0.5, 1.0], [-0.3, 0.2, 1.0]]), [2.0, 2.0, 2.0, 2.0],
                      [[1, 1, 1], [5, 5, 5], [0, 0, 0], [1e-9, 1e-9, 1e-9]])
    eng = make_engine(ctx, scene)
    eng.set_lights(base)
    eng.render()
    assert [eng.light_active(i) for i in range(4)] == [True, False, False, False]
    assert eng.kit.counters["shadow_map"] == 1
    skipped = eng.output.read_hdr()
    eng.release()
    full = make_engine(ctx, scene, skip_threshold=0.0)
    full.set_lights(AreaLights(base.direction, base.sigma, base.intensity))
    full.render()
    assert full.kit.counters["shadow_map"] == 2  # the 1e-9 light is computed, the back and black ones never can be
    np.testing.assert_allclose(skipped, full.output.read_hdr(), rtol=1e-5, atol=1e-7)
    full.release()


@pytest.mark.parametrize("soft", ["pcss", "csm"])
def test_a_light_going_out_binds_a_stand_in_sampled_like_the_real_maps(ctx, scene, soft):
    """llvmpipe compiles a shader variant per kind of texture bound at each unit (format, filter,
    wrap, power-of-two sides): a slot whose light went out binds a stand-in of the same kind as the
    shadow maps and pre-filtered bases, or dragging a light below the horizon froze the window for
    0.6-1.5 s while a new variant compiled (issue 45)."""
    def kind(tex):
        pot = tuple(v & (v - 1) == 0 for v in tex.size)
        return tex.components, tex.dtype, tex.filter, tex.repeat_x, tex.repeat_y, pot

    eng = make_engine(ctx, scene, soft=soft, terms=6)  # 6 terms: atlases 3 tiles wide, sides not powers of two
    lights = AreaLights(unit([[0.3, 0.4, 1.0], [-0.3, 0.2, 1.0]]), [2.0, 2.0], [[1, 1, 1], [1, 1, 1]])
    eng.set_lights(lights)
    eng.set_look(Look(shadows="soft"))
    eng.render()
    real = eng._lights[0]
    assert kind(eng.light_pass.stand_in_shadow_map) == kind(real.shadow_map)
    if soft == "csm":
        assert kind(eng.light_pass.stand_in_filtered) == kind(real.filtered)
    eng.release()


def used_programs(eng, fragment: str) -> list:
    """The cache keys of the programs with this fragment shader that the engine drew with (the
    context's program cache is shared by every engine on it)."""
    drawn = set(eng.kit.fullscreen_vaos)
    return [k for k, prog in eng.kit.programs._programs.items() if k[1] == fragment and prog.glo in drawn]


def test_matte_scene_skips_specular(ctx):
    sc = plane_and_box(48, specular=0.0)
    eng = make_engine(ctx, sc)
    eng.set_lights(AreaLights(unit([[0.1, 0.2, 1.0]]), [1.0], [[1, 1, 1]]))
    eng.render()
    light_programs = used_programs(eng, "light_pass.frag.glsl")
    assert light_programs and all("SPECULAR" not in dict(k[2]) for k in light_programs)
    out = eng.output.read_light(0)
    expected = np.broadcast_to((0.5 * out["diffuse"] * out["visibility_soft"])[..., None], (48, 48, 3))
    np.testing.assert_allclose(eng.output.read_hdr(), expected, rtol=1e-6)
    eng.release()


def test_weak_light_on_a_mirror_highlight_is_not_skipped(ctx):
    """A light far weaker than another can still dominate where it is mirrored (roughness 0): the
    skip bound accounts for the specular peak."""
    sc = plane_and_box(48, box=False, specular=1.0, roughness=0.0)
    lights = AreaLights(unit([[0.8, 0.0, 0.6], [0.0, 0.0, 1.0]]), [0.0, 0.0], [[1, 1, 1], [5e-6, 5e-6, 5e-6]])
    eng = make_engine(ctx, sc)
    eng.set_lights(lights)
    eng.render()
    full = make_engine(ctx, sc, skip_threshold=0.0)
    full.set_lights(lights)
    full.render()
    assert eng.light_active(1)
    np.testing.assert_allclose(eng.output.read_hdr(), full.output.read_hdr(), rtol=1e-5, atol=1e-9)
    eng.release()
    full.release()


@pytest.mark.parametrize("soft", ["csm", "pcss"])
def test_any_sequence_of_changes_matches_a_fresh_render(ctx, scene, soft):
    """Cache rules under light-count changes, skip/unskip, sigma crossing hard_sigma and pyramid
    levels (CSM) or blocker-map sizes (PCSS), and visibility modes: every frame equals a fresh engine's."""
    d = unit([[0.3, 0.4, 1.0], [-0.5, 0.2, 1.0], [0.1, 0.9, 0.5], [0.6, -0.1, 0.8]])
    base = AreaLights(d, [3.0, 6.0, 0.0, 12.0], [[1, 1, 1], [0.5, 0.4, 0.3], [0.2, 0.2, 0.2], [0.3, 0.3, 0.3]])
    steps = [
        ("set", base),
        ("set", base.with_sigma(2, 40.0).with_sigma(0, 0.0)),  # crosses hard_sigma both ways, new level
        ("set", AreaLights(base.direction[:2], base.sigma[:2], base.intensity[:2])),  # fewer lights
        ("set", AreaLights(base.direction, base.sigma, [[1, 1, 1], [0, 0, 0], [0.2, 0.2, 0.2], [0.3, 0.3, 0.3]])),
        ("set", base.rotated(30.0)),  # light 1 comes back, rotated while it was skipped
        ("vis", "hard"),
        ("set", base.rotated(30.0).with_sigma(3, 1.5)),
        ("vis", "soft"),
    ]
    eng = make_engine(ctx, scene, soft=soft)
    vis = "soft"
    for kind, value in steps:
        if kind == "set":
            lights = value
            eng.set_lights(value)
        else:
            vis = value
            eng.set_visibility(value)
        eng.render()
        fresh = make_engine(ctx, scene, soft=soft)
        fresh.set_lights(lights)
        fresh.set_visibility(vis)
        fresh.render()
        np.testing.assert_array_equal(eng.output.read_hdr(), fresh.output.read_hdr(), err_msg=f"after {kind} {value}")
        fresh.release()
    eng.release()


@pytest.mark.parametrize("options, message", [
    ({"shadow_resolution": 500}, "power of two"),
    ({"shadow_resolution": 0}, "power of two"),
    ({"terms": 1}, "terms"),
    ({"shadow_step": -1}, "shadow step"),
    ({"prefilter": "box"}, "prefilter"),
    ({"soft": "vsm"}, "soft shadows"),
])
def test_bad_options_are_clear_errors(options, message):
    from viewer.errors import InputError

    with pytest.raises(InputError, match=message):
        EngineOptions(**options)


def test_extreme_exposure_saturates_instead_of_going_black(ctx, scene):
    eng = make_engine(ctx, scene)
    eng.set_lights(AreaLights(unit([[0.3, 0.4, 1.0]]), [2.0], [[1e5, 1e5, 1e5]]))
    relook(eng, exposure=40.0)
    eng.render()
    lit = eng.output.read_hdr().max(axis=-1) > 0
    assert lit.mean() > 0.9 and (eng.output.read_display()[lit] == 255).all()
    eng.release()


def test_filtered_basis_is_readable_and_bounded(ctx, scene):
    eng = make_engine(ctx, scene, soft="csm")
    eng.set_lights(AreaLights(unit([[0.3, 0.4, 1.0], [0.1, 0.2, 1.0]]), [6.0, 0.0], [[1, 1, 1], [1, 1, 1]]))
    eng.render()
    basis = eng.output.read_filtered_basis(0)
    assert basis.shape[0] == 8 and basis.shape[1] == basis.shape[2] == 256 >> eng._lights[0].plan.level
    assert np.abs(basis).max() <= 1.0 + 1e-6  # averages of cosines and sines
    with pytest.raises(ValueError, match="sigma ~ 0"):
        eng.output.read_filtered_basis(1)
    eng.release()


def test_many_lights_compose_linearly(ctx):
    """70 lights (two composite chunks, 18 light-pass groups) equal the sum of two partial renders."""
    sc = plane_and_box(48)
    rng = np.random.default_rng(5)
    d = rng.normal(size=(70, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.2
    lights = AreaLights(unit(d), rng.uniform(0, 10, 70), rng.uniform(0, 1, (70, 3)))
    parts = []
    for sel in (slice(0, 70), slice(0, 41), slice(41, 70)):
        eng = make_engine(ctx, sc, shadow_resolution=128, skip_threshold=0.0)
        eng.set_lights(AreaLights(lights.direction[sel], lights.sigma[sel], lights.intensity[sel]))
        eng.render()
        parts.append(eng.output.read_hdr())
        eng.release()
    np.testing.assert_allclose(parts[0], parts[1] + parts[2], rtol=1e-5, atol=1e-7)


def test_shadow_modes_do_only_the_work_they_show(ctx, scene):
    """Hard shadows skip the CSM filtering, no shadows skip the shadow maps too; switching back to
    soft shadows computes what was skipped and gives exactly the soft-only engine's image."""
    lights = AreaLights(unit([[0.3, 0.4, 1.0], [-0.5, 0.2, 1.0]]), [3.0, 6.0], [[1, 1, 1], [0.5, 0.4, 0.3]])
    eng = make_engine(ctx, scene, soft="csm")
    eng.set_visibility("none")
    eng.set_lights(lights)
    eng.render()
    assert eng.kit.counters["shadow_map"] == 0 and eng.kit.counters["csm_basis"] == 0
    unshadowed = eng.output.read_hdr()
    eng.set_visibility("hard")
    eng.set_lights(lights.rotated(15.0))
    eng.render()
    assert eng.kit.counters["shadow_map"] == 2 and eng.kit.counters["csm_basis"] == 0
    hard = eng.output.read_hdr()
    eng.set_visibility("soft")
    eng.render()
    assert eng.kit.counters["shadow_map"] == 2 and eng.kit.counters["csm_basis"] == 2
    soft = eng.output.read_hdr()
    ref = make_engine(ctx, scene, soft="csm")
    ref.set_lights(lights.rotated(15.0))
    ref.render()
    np.testing.assert_array_equal(soft, ref.output.read_hdr())
    ref.set_visibility("hard")
    ref.render()
    np.testing.assert_array_equal(hard, ref.output.read_hdr())
    ref.set_lights(lights)
    ref.set_visibility("none")
    ref.render()
    np.testing.assert_allclose(unshadowed, ref.output.read_hdr(), rtol=1e-6, atol=1e-7)
    out = ref.output.read_light(0)  # no shadows computed: unit visibility wherever the light shades
    assert out["diffuse"].sum() > 0 and (out["visibility_soft"][out["diffuse"] > 0] == 1.0).all()
    assert unshadowed.sum() > hard.sum()  # (at different rotations, but the box shadows either)
    eng.release()
    ref.release()


def test_components_and_views(ctx):
    sc = plane_and_box(48, specular=0.8, roughness=0.4)
    lights = AreaLights(unit([[0.3, 0.4, 1.0], [-0.2, 0.5, 1.0]]), [2.0, 0.0], [[1, 0.8, 0.6], [0.3, 0.3, 0.3]])
    eng = make_engine(ctx, sc)
    eng.set_lights(lights)
    eng.render()
    full = eng.output.read_hdr()
    outs = [eng.output.read_light(i) for i in range(2)]
    diff = sum(o["visibility_soft"][..., None] * o["diffuse"][..., None] * lights.intensity[i] for i, o in enumerate(outs))
    spec = sum(o["visibility_soft"][..., None] * o["specular"][..., None] * lights.intensity[i] for i, o in enumerate(outs))
    albedo = sc.albedo * sc.mask[..., None]
    np.testing.assert_allclose(full, albedo * diff + spec, rtol=1e-5, atol=1e-7)
    passes = dict(eng.kit.counters)
    relook(eng, diffuse=False, specular=True)
    eng.render()
    np.testing.assert_allclose(eng.output.read_hdr(), spec, rtol=1e-5, atol=1e-7)
    relook(eng, diffuse=True, specular=False)
    eng.render()
    np.testing.assert_allclose(eng.output.read_hdr(), albedo * diff, rtol=1e-5, atol=1e-7)
    relook(eng, diffuse=True, specular=True)
    eng.set_view("diffuse_shading")
    eng.render()
    np.testing.assert_allclose(eng.output.read_hdr(), diff, rtol=1e-5, atol=1e-7)
    eng.set_view("specular_shading")
    eng.render()
    np.testing.assert_allclose(eng.output.read_hdr(), spec, rtol=1e-5, atol=1e-7)
    # none of this redid a light pass
    assert eng.kit.counters["light_pass"] == passes["light_pass"] and eng.kit.counters["shadow_map"] == passes["shadow_map"]
    m = sc.mask
    eng.set_view("final")
    eng.render()
    composites = eng.kit.counters["composite"]
    eng.set_view("normal")
    eng.render()
    assert eng.kit.counters["composite"] == composites  # an inspection view redoes the display only
    np.testing.assert_array_equal(eng.output.read_hdr(), full)  # and the HDR output stays the relit image
    shown = eng.output.read_display().astype(np.float32) / 255
    np.testing.assert_allclose(shown[m], sc.normal[m] * 0.5 + 0.5, atol=1 / 255 + 1e-6)
    eng.set_view("roughness")
    eng.render()
    np.testing.assert_allclose(eng.output.read_display()[m][:, 0] / 255, sc.roughness[m], atol=1 / 255 + 1e-6)
    eng.set_view("shadow", light=0)
    eng.render()
    np.testing.assert_allclose(eng.output.read_display()[m][:, 0] / 255, np.clip(outs[0]["visibility_soft"][m], 0, 1), atol=1 / 255 + 1e-6)
    eng.set_view("final")
    eng.render()
    np.testing.assert_array_equal(eng.output.read_hdr(), full)
    with pytest.raises(ValueError):
        eng.set_view("shadow", light=5)
    eng.release()


def test_leave_out_off_does_all_the_work_for_the_same_image(ctx):
    """leave_out=False (what `relight bench report` measures the policy against) computes every
    light, filters at sigma ~ 0 and runs specular on a matte scene; the image stays the same."""
    sc = plane_and_box(48, specular=0.0)
    lights = AreaLights(unit([[0.3, 0.4, 1.0], [0.5, 0.5, 1.0], [-0.2, 0.3, 1.0]]), [1.0, 1.0, 0.01],
                        [[1, 1, 1], [0, 0, 0], [2, 2, 2]])
    out = {}
    for leave_out in (True, False):
        eng = make_engine(ctx, sc, leave_out=leave_out, soft="csm")
        eng.set_lights(lights)
        eng.render()
        specular = any("SPECULAR" in dict(k[2]) for k in used_programs(eng, "light_pass.frag.glsl"))
        out[leave_out] = (eng.output.read_hdr(), eng.kit.counters["shadow_map"], eng.kit.counters["prefilter"], specular)
        eng.release()
    (on, maps_on, filters_on, spec_on), (off, maps_off, filters_off, spec_off) = out[True], out[False]
    assert (maps_on, filters_on, spec_on) == (2, 1, False)
    assert (maps_off, filters_off, spec_off) == (3, 3, True)
    assert np.abs(on - off).mean() < 2e-3 * off.mean()


def test_frame_cache_rules(ctx, scene):
    """A scene with a frame layer: each change redoes exactly the frame passes whose declared inputs
    it touches (the frame background only for the background, its colour, the map or its turn)."""
    from dataclasses import replace

    from viewer.scene.bundle import FrameLayer

    up = lambda a: np.repeat(np.repeat(a, 2, axis=0), 2, axis=1)  # noqa: E731
    frame = FrameLayer(albedo=up(scene.albedo), alpha=up(scene.mask.astype(np.float32)), photo=up(scene.albedo) * 0.5)
    sc = replace(scene, frame=frame)
    lights = AreaLights(unit([[0.3, 0.4, 1.0], [-0.5, 0.2, 1.0]]), [3.0, 0.0], [[1, 1, 1], [0.5, 0.4, 0.3]])
    eng = make_engine(ctx, sc)
    eng.set_lights(lights)
    eng.render()
    assert eng.output_size == (192, 192)
    assert {k: eng.kit.counters[k] for k in ("composite", "frame_background", "frame_mipmaps", "frame_composite")} == \
        {"composite": 1, "frame_background": 1, "frame_mipmaps": 1, "frame_composite": 1}

    def delta(action):
        start = dict(eng.kit.counters)
        action()
        eng.render()
        return {k: v - start.get(k, 0) for k, v in eng.kit.counters.items() if v - start.get(k, 0)}

    assert delta(lambda: relook(eng, exposure=1.0)) == {"frame_composite": 1}
    assert delta(lambda: relook(eng, background_color=(0.5, 0.2, 0.1))) == {"frame_background": 1, "frame_composite": 1}
    # the yaw turns the lights and the map behind together (Engine.set_look): the lights' shadows and
    # their light pass, then the frame
    assert delta(lambda: relook(eng, yaw=30.0)) == {"shadow_map": 2, "light_pass": 1, "composite": 1, "frame_mipmaps": 1,
                                                     "frame_background": 1, "frame_composite": 1}
    assert delta(lambda: eng.set_environment(np.ones((8, 16, 3), np.float32))) == {"frame_background": 1, "frame_composite": 1}
    assert delta(lambda: eng.set_lights(lights.scaled(2.0))) == {"composite": 1, "frame_mipmaps": 1, "frame_composite": 1}
    assert delta(lambda: eng.set_view("albedo")) == {"display": 1}  # an inspection view: the frame passes wait
    assert delta(lambda: eng.set_view("final")) == {"frame_mipmaps": 1, "frame_composite": 1}
    assert delta(lambda: eng.render()) == {}
    eng.release()


def test_before_and_after_shows_the_photo_left_of_the_split(ctx, scene):
    """look.compare: the display shows the original photo (as it was: sRGB of its linear values)
    left of the split, a white line at it, and the relit frame right of it; the HDR outputs are
    unchanged, and the split costs one frame composite."""
    from dataclasses import replace

    from viewer.scene.bundle import FrameLayer

    up = lambda a: np.repeat(np.repeat(a, 2, axis=0), 2, axis=1)  # noqa: E731
    photo = up(scene.albedo) * 0.5
    sc = replace(scene, frame=FrameLayer(albedo=up(scene.albedo), alpha=up(scene.mask.astype(np.float32)), photo=photo))
    eng = make_engine(ctx, sc)
    eng.set_lights(AreaLights(unit([[0.3, 0.4, 1.0]]), [3.0], [[2, 2, 2]]))
    eng.render()
    after, hdr = eng.output.read_display().astype(int), eng.output.read_hdr()
    start = dict(eng.kit.counters)
    relook(eng, compare=0.25)
    eng.render()
    assert {k: v - start.get(k, 0) for k, v in eng.kit.counters.items() if v - start.get(k, 0)} == {"frame_composite": 1}
    split = eng.output.read_display().astype(int)
    w = split.shape[1]
    srgb = np.where(photo <= 0.0031308, 12.92 * photo, 1.055 * np.power(np.maximum(photo, 0.0031308), 1 / 2.4) - 0.055)
    assert np.abs(split[:, : w // 4 - 1] - np.rint(255 * srgb[:, : w // 4 - 1])).max() <= 1
    assert (split[:, w // 4 - 1: w // 4 + 1] == 255).all()
    np.testing.assert_array_equal(split[:, w // 4 + 1:], after[:, w // 4 + 1:])
    assert np.abs(split[:, : w // 4 - 1] - after[:, : w // 4 - 1]).mean() > 5  # the photo is not the relit frame
    np.testing.assert_array_equal(eng.output.read_hdr(), hdr)
    eng.release()


def test_passes_declare_what_makes_them_stale(ctx, scene):
    """The cache table of docs/engine.md is the passes' own declarations: each change names the
    inputs it touches, and the passes that read them (directly or through a pass they read) run."""
    eng = make_engine(ctx, scene, soft="csm")  # the paper's CSM: the longest chain of passes
    readers = {}
    for p in (*eng.stale.light_passes, *eng.stale.frame_passes):
        for what in (*p.inputs, *getattr(p, "whole_inputs", ())):
            readers.setdefault(what, set()).add(p.name)
    assert readers["direction"] == {"shadow_map", "light_pass"}
    # the light pass reads sigma too: it widens the specular lobe
    assert readers["sigma"] == {"csm_basis", "light_pass"} and scene.has_specular
    assert readers["shadow_map"] == {"csm_basis", "light_pass"} and readers["csm_basis"] == {"prefilter"}
    assert readers["prefilter"] == {"light_pass"} and readers["light_pass"] == {"composite", "ground_shadow"}
    assert readers["intensity"] == {"composite", "ground_shadow"} and readers["display"] == {"display"}
    assert readers["composite"] == {"display"} and readers["ground_shadow"] == {"display"}
    eng.release()


def test_a_map_wider_than_the_textures_is_averaged_down_not_black():
    from viewer.gl.scene_resources import fit_environment

    rng = np.random.default_rng(3)
    px = rng.random((64, 130, 3)).astype(np.float32)
    small = fit_environment(px, 32)
    assert small.shape == (64 // 5, 130 // 5, 3)  # factor 5: the smallest that fits 32 texels
    np.testing.assert_allclose(small[1, 2], px[5:10, 10:15].mean(axis=(0, 1)), rtol=1e-5)
    assert fit_environment(px, 130) is px


def test_contact_hardening_cache_rules(ctx, scene):
    """Contact-hardening soft shadows read the shadow map itself: no CSM basis or pre-filter ever
    runs, and a sigma edit redoes the light pass alone (then the composite)."""
    lights = AreaLights(unit([[0.3, 0.4, 1.0], [-0.5, 0.2, 1.0]]), [3.0, 6.0], [[1, 1, 1], [0.5, 0.4, 0.3]])
    eng = Engine(ctx, scene, EngineOptions(soft="pcss"))
    eng.set_lights(lights)
    eng.render()
    assert eng.kit.counters.get("csm_basis", 0) == 0 and eng.kit.counters.get("prefilter", 0) == 0
    start = dict(eng.kit.counters)
    eng.set_lights(lights.with_sigma(1, 9.0))
    eng.render()
    assert {k: v - start.get(k, 0) for k, v in eng.kit.counters.items() if v - start.get(k, 0)} == {
        "light_pass": 1, "composite": 1, "display": 1}
    soft = eng.output.read_light(1)["visibility_soft"]
    assert np.isfinite(soft).all() and 0.0 <= soft.min() and soft.max() <= 1.0
    eng.release()


def test_refined_shadows_read_the_default_soft_shadows(ctx, scene):
    """The refinement network's visibility replaces the (PCSS) soft visibility in the composite:
    all zeros gives a black person, all ones the unshadowed image."""
    lights = AreaLights(unit([[0.3, 0.4, 1.0], [-0.5, 0.2, 1.0]]), [3.0, 6.0], [[1, 1, 1], [0.5, 0.4, 0.3]])
    eng = make_engine(ctx, scene)
    assert eng.options.soft == "pcss"
    eng.set_lights(lights)
    eng.set_visibility("none")
    eng.render()
    unshadowed = eng.output.read_hdr()
    eng.set_visibility("refined")
    shape = (2, scene.height, scene.width)
    for value, expected in ((0.0, np.zeros_like(unshadowed)), (1.0, unshadowed)):
        eng.set_refined_visibility(np.full(shape, value, np.float32))
        eng.render()
        np.testing.assert_allclose(eng.output.read_hdr(), expected, atol=1e-4 * float(unshadowed.max()))
    eng.release()


def test_a_budgeted_render_keeps_the_last_frame_until_it_is_complete_then_matches_a_full_render(ctx, scene):
    """Engine.render(budget): the window brings a new map or person in over several frames; the
    display keeps the last complete frame meanwhile, and the frame it ends with is the full render's."""
    d = unit([[0.3, 0.4, 1.0], [-0.5, 0.2, 1.0], [0.1, 0.9, 0.5], [0.6, -0.1, 0.8], [0.0, 1.0, 0.2]])
    lights = AreaLights(d, [3.0, 6.0, 0.5, 12.0, 2.0], [[1, 1, 1], [0.5, 0.4, 0.3], [0.2, 0.2, 0.2], [0.3, 0.3, 0.3],
                                                           [0.4, 0.4, 0.4]])
    eng = make_engine(ctx, scene)
    eng.set_lights(lights)
    eng.render()
    assert eng.complete
    before = eng.output.read_display().copy()
    eng.set_lights(lights.rotated(70.0))
    steps = render_by_units(eng, before, limit=100)  # one unit of work a call, never a half-updated frame
    assert steps > 3
    fresh = make_engine(ctx, scene)
    fresh.set_lights(lights.rotated(70.0))
    fresh.render()
    np.testing.assert_array_equal(eng.output.read_display(), fresh.output.read_display())
    assert not np.array_equal(eng.output.read_display(), before)
    # the light pass goes in bands of rows (a unit each); a change while a group's bands are part-way
    # starts that group again, so no band of the old lighting stays in the frame
    from viewer.gl.light_pass import BANDS

    before = eng.output.read_display().copy()
    runs = eng.kit.counters["light_pass"]
    eng.set_lights(lights.rotated(20.0))

    def turn_mid_group(calls):
        if eng.light_pass._next is not None and eng.light_pass._next[1] == 2 and eng.lights.direction[0, 0] != turned[0, 0]:
            eng.set_lights(lights.rotated(-30.0))

    turned = lights.rotated(-30.0).direction
    render_by_units(eng, before, turn_mid_group)
    assert eng.kit.counters["light_pass"] - runs > 2 * BANDS  # two groups in bands, and one started again
    fresh.set_lights(lights.rotated(-30.0))
    fresh.render()
    np.testing.assert_array_equal(eng.output.read_display(), fresh.output.read_display())
    fresh.release()
    eng.release()


def test_shading_views_are_exposed_for_display_not_clipped_to_white(ctx, scene):
    """The diffuse-shading view (albedo 1) under a look exposed for albedos of a few tenths clipped
    to white; it is shown so that every light head-on is white."""
    from viewer.scene.look import Look

    eng = make_engine(ctx, scene)
    eng.set_lights(AreaLights(unit([[0.3, 0.5, 1.0], [-0.4, 0.3, 1.0]]), [2.0, 4.0], [[30.0, 30.0, 30.0], [10.0, 9.0, 8.0]]))
    look = Look(background="color", exposure=1.0, tonemap="clamp")
    eng.set_look(look)
    eng.render()
    relit = eng.output.read_display()[scene.mask]
    assert (relit >= 254).all(axis=-1).mean() > 0.5  # this look is far too bright for shading alone...
    eng.set_look(look.replace(view="diffuse_shading"))
    eng.render()
    shading = eng.output.read_display()[scene.mask].astype(np.float32)
    assert (shading >= 254).all(axis=-1).mean() < 0.01 and shading.max() > 120  # ...which shows, unclipped
    eng.release()


def test_the_engine_applies_the_whole_look(ctx, scene):
    """The look's yaw and tilt turn the map's lights (with the map behind), its intensity scales
    them, its placed intensity the placed lights, which stay fixed to the camera; the background
    falls back to what the scene has. Callers hand the lights as fitted and the look as asked."""
    lights = AreaLights(unit([[0.3, 0.4, 1.0], [-0.5, 0.2, 1.0]]), [3.0, 6.0], [[1, 1, 1], [0.5, 0.4, 0.3]])
    placed = AreaLights(unit([[0.0, 0.2, 1.0]]), [2.0], [[0.7, 0.7, 0.7]])
    eng = make_engine(ctx, scene)
    eng.set_lights(lights, placed)
    eng.set_look(Look(yaw=40.0, tilt=-10.0, intensity=2.0, placed_intensity=0.5, background="color"))
    want = lights.rotated(40.0, -10.0).scaled(2.0).followed_by(placed.scaled(0.5))
    np.testing.assert_array_equal(eng.lights.direction, want.direction)
    np.testing.assert_array_equal(eng.lights.intensity, want.intensity)
    eng.render()
    turned = eng.output.read_hdr()
    eng.set_look(Look(background="color"))  # back to yaw 0: the lights as given
    np.testing.assert_array_equal(eng.lights.direction, lights.followed_by(placed).direction)
    other = make_engine(ctx, scene)  # the same picture from the lights turned by hand, as callers did before
    other.set_lights(want)
    other.set_look(Look(background="color"))
    np.testing.assert_array_equal(other.render().output.read_hdr(), turned)
    # no map and no photo behind: the background asked for falls back, no error
    assert scene.background is None
    for asked in ("environment", "photo"):
        eng.set_look(Look(background=asked))
        assert eng.look.background == "color" and eng.looks.asked.background == asked
    eng.set_environment(np.ones((8, 16, 3), np.float32))
    eng.set_look(Look(background="environment"))
    assert eng.look.background == "environment"
    eng.set_environment(None)  # a look lit by a light file after one with a map
    assert eng.look.background == "color"
    eng.release()
    other.release()


def test_the_pass_table_in_the_docs_is_the_passes_declarations(ctx, scene):
    """docs/engine.md's cache table is the one place the passes and their inputs are written (the
    engine's docstring points there): every pass of an image scene and of a frame scene (CSM and
    PCSS) has its row, every input it declares is named in the row, and the row names no input
    that the pass does not declare."""
    import re
    from dataclasses import replace
    from pathlib import Path

    from viewer.scene.bundle import FrameLayer

    text = (Path(__file__).resolve().parents[1] / "docs" / "engine.md").read_text(encoding="utf-8")
    rows = {m.group(1): m.group(2) for m in re.finditer(r"^\|[^|`]*`(\w+Pass)`[^|]*\|[^|]*\|([^|]*)\|", text, re.M)}
    up = lambda a: np.repeat(np.repeat(a, 2, axis=0), 2, axis=1)  # noqa: E731
    framed = replace(scene, frame=FrameLayer(albedo=up(scene.albedo), alpha=up(scene.mask.astype(np.float32)),
                                             photo=up(scene.albedo) * 0.5, skin=up(scene.mask.astype(np.float32))))
    declared: dict[str, set] = {}
    for sc in (scene, framed):
        for soft in ("csm", "pcss"):
            eng = make_engine(ctx, sc, soft=soft)
            for p in (*eng.stale.light_passes, *eng.stale.frame_passes):
                declared.setdefault(type(p).__name__, set()).update(p.inputs, getattr(p, "whole_inputs", ()))
            eng.release()
    names = set().union(*declared.values()) | {p for p in declared}
    for cls, inputs in declared.items():
        assert cls in rows, f"docs/engine.md has no row for {cls}"
        words = set(re.findall(r"[a-z_]+", rows[cls]))
        assert inputs <= words, (cls, inputs - words)
        assert (words & set().union(*declared.values())) <= inputs, (cls, (words & names) - inputs)
