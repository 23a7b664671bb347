"""Contact-hardening soft shadows (shaders/pcss.glsl) on a box over a plane, against the ray tracer:
the penumbra of a real area light widens with the blocker-receiver distance, and so must ours,
by about as much; the paper's CSM blurs every shadow alike."""

from __future__ import annotations

import numpy as np
import pytest

from viewer.gl import Engine, EngineOptions
from viewer.lab.bench.contact import LIGHT, ContactConfig, penumbra_widths
from viewer.lab.scenes import plane_and_box
from viewer.scene.area_lights import AreaLights


@pytest.fixture(scope="module")
def widths(ctx):
    """Penumbra widths (pixels) at 0.15 and 0.6 m between blocker and receiver: PCSS, CSM, Mitsuba."""
    return penumbra_widths(ctx, ContactConfig(heights=(0.15, 0.6)), methods=("pcss", "csm"))


def test_penumbra_widens_with_the_distance_to_the_blocker(widths):
    low, high = widths["truth"]
    assert high > 2.0 * low  # the ray tracer: a real area light
    low, high = widths["pcss"]
    assert high > 2.0 * low
    growth = np.array(widths["pcss"][1] / widths["pcss"][0]) / (widths["truth"][1] / widths["truth"][0])
    assert 0.6 < growth < 1.6
    assert 0.6 < widths["pcss"][1] / widths["truth"][1] < 1.6  # and about as wide


def test_csm_is_too_soft_near_contact(widths):
    # one blur for every shadow: near the blocker the paper's CSM is far wider than the truth
    # (measured 12.4 pixels against 7.5), what the contact-hardening method fixes (5.9)
    assert widths["csm"][0] > 1.6 * widths["truth"][0]
    assert abs(widths["pcss"][0] - widths["truth"][0]) < abs(widths["csm"][0] - widths["truth"][0])


def test_extreme_lights_stay_finite_and_bounded(ctx):
    """Sigma 0, tiny and the largest allowed, a grazing and a below-horizon light: visibility in [0, 1]."""
    from viewer.scene.area_lights import MAX_SIGMA

    scene = plane_and_box(48)
    grazing = np.array([np.cos(np.radians(2.0)), 0.0, np.sin(np.radians(2.0))])
    dirs = np.array([LIGHT, LIGHT, LIGHT, grazing, [0.0, 0.3, -1.0]], np.float32)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    eng = Engine(ctx, scene, EngineOptions(soft="pcss", shadow_step=1))
    eng.set_lights(AreaLights(dirs, [0.0, 1e-3, MAX_SIGMA, 10.0, 10.0], np.ones((5, 3), np.float32)))
    eng.render()
    for i in range(5):
        v = eng.output.read_light(i)["visibility_soft"]
        assert np.isfinite(v).all() and v.min() >= 0.0 and v.max() <= 1.0
    assert np.isfinite(eng.output.read_hdr()).all()
    eng.release()


def test_a_sharp_shadows_edge_is_filtered_not_a_staircase(ctx):
    """A small light's shadow of the box on the plane: with the penumbra at least PCSS_MIN_TEXELS
    shadow-map texels wide, the edge has intermediate values and no jump from lit to shadowed
    between neighbours (the staircase a work pixel then shows as a block in a larger output);
    the hard test keeps its binary edge."""
    from viewer.scene import shadow_space

    scene = plane_and_box(96)
    eng = Engine(ctx, scene, EngineOptions(soft="pcss", shadow_step=1, shadow_resolution=128))
    eng.set_lights(AreaLights(np.array([LIGHT], np.float32), [0.2], np.ones((1, 3), np.float32)))
    eng.render()
    out = eng.output.read_light(0)
    soft, hard = out["visibility_soft"], out["visibility_hard"]
    eng.release()
    assert set(np.unique(hard)) <= {0.0, 1.0}
    partial = (soft > 0.05) & (soft < 0.95)
    assert partial.sum() >= 0.5 * (np.abs(np.diff(hard, axis=1)) > 0.5).sum()  # the edge is soft all along
    assert max(np.abs(np.diff(soft, axis=0)).max(), np.abs(np.diff(soft, axis=1)).max()) < 0.95
    assert shadow_space.PCSS_MIN_TEXELS > 0


@pytest.mark.parametrize("sigma, tile", [(0.7, 16), (3.0, 16), (40.0, 16), (300.0, 32)])
def test_the_blur_pass_is_the_clamped_gaussian_with_taps_bounded_by_the_tile(ctx, sigma, tile):
    """gaussian_blur.frag.glsl against the clamp-to-edge Gaussian in numpy, per tile of an atlas of
    three: a kernel many tiles wide (the exact prefilter of a wide light) gives the same result,
    its clamped taps' weight added to the edge texels once."""
    import math

    from viewer.gl.prefilter import BlurPlan
    from viewer.gl.programs import ProgramCache

    rng = np.random.default_rng(3)
    data = rng.random((tile, 3 * tile, 4)).astype(np.float32)
    plan = BlurPlan(0, sigma, int(math.ceil(3.0 * sigma)))
    prog = ProgramCache(ctx).get("fullscreen.vert.glsl", "gaussian_blur.frag.glsl")
    src = ctx.texture((3 * tile, tile), 4, data.tobytes(), dtype="f4")
    out = ctx.texture((3 * tile, tile), 4, dtype="f4")
    fbo = ctx.framebuffer([out])
    vao = ctx.vertex_array(prog, [])
    for name, value in (("radius", plan.radius), ("sigma", plan.sigma), ("norm", plan.norm), ("tile_size", tile),
                        ("source", 0), ("axis", (1, 0))):
        prog[name] = value
    fbo.use()
    src.use(0)
    vao.render(vertices=3)
    got = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(tile, 3 * tile, 4)
    offsets = np.arange(-plan.radius, plan.radius + 1)
    weights = np.exp(-0.5 * offsets.astype(np.float64) ** 2 / sigma**2)
    weights /= weights.sum()
    want = np.zeros_like(data, dtype=np.float64)
    for t in range(3):
        tile_data = data[:, t * tile:(t + 1) * tile].astype(np.float64)
        for x in range(tile):
            idx = np.clip(x + offsets, 0, tile - 1)
            want[:, t * tile + x] = np.tensordot(weights, tile_data[:, idx], axes=(0, 1))
    for r in (vao, fbo, out, src):
        r.release()
    assert np.abs(got - want).max() < 2e-5  # measured 2e-7 to 7e-6


def test_a_soft_shadow_method_defined_only_here_is_found_and_rendered(ctx):
    """A soft-shadow method is one registered module of viewer/gl/soft/ (its GLSL and its twin): one defined
    only in this test, whose soft visibility is half the shadow map's, becomes an engine option and a
    --soft choice, renders through the light and ground passes, and its twin matches its shader."""
    import torch

    from viewer.cli.parser import build_parser
    from viewer.gl.soft import METHODS, SoftMethod, register_soft_method, soft_method
    from viewer.twin import csm, render as twin_render

    @register_soft_method
    class HalfHard(SoftMethod):
        name = "half-hard"

        def glsl(self) -> str:
            return ("float soft_visibility(int j, sampler2D shadow_map, sampler2D filtered_basis, vec3 uvd, vec3 n, "
                    "vec3 l, float bias) { return 0.5 * hard_visibility(shadow_map, uvd, bias); }")

        def twin(self, depth, sigma, frames, u, v, d, bias, normal, terms):
            return 0.5 * csm.hard_visibility(depth, u, v, d, bias)

    try:
        assert soft_method("half-hard").reads == ("sigma",)
        args = build_parser().parse_args(["render", "scene", "--soft", "half-hard", "-o", "x.png"])
        assert args.soft == "half-hard"
        scene = plane_and_box(48)
        lights = AreaLights(np.array([LIGHT], np.float32), [2.0], np.ones((1, 3), np.float32))
        eng = Engine(ctx, scene, EngineOptions(soft="half-hard", shadow_step=1, shadow_resolution=128))
        eng.set_lights(lights)
        eng.render()
        out = eng.output.read_light(0)
        assert eng.kit.counters["csm_basis"] == 0  # not pre-filtered: no CSM basis made
        assert np.allclose(out["visibility_soft"], 0.5 * out["visibility_hard"])
        assert (out["visibility_hard"] == 0).any() and (out["visibility_hard"] == 1).any()
        eng.release()
        with torch.no_grad():
            twin = twin_render(scene, lights, shadow_resolution=128, shadow_step=1, soft=soft_method("half-hard").twin)
        assert np.allclose(twin.soft_visibility.numpy()[0], 0.5 * twin.hard_visibility.numpy()[0])
    finally:
        del METHODS["half-hard"]
