"""Light fitting: map samples, analytic reference shading, the fitters on stiff maps, cache, CLI."""

import json
import warnings

import numpy as np
import pytest
import torch
from conftest import SHARED_DATA

from viewer.lab.bench.lightfit_evaluate import held_out, relative_l1, shading_errors
from viewer.lighting.envmap import EnvMap, load_envmap, pixel_directions, save_envmap
from viewer.lighting.lightfit import cache_path, lights_for_map, map_hash
from viewer.lighting.lightfit.fit import fit_lights
from viewer.lighting.lightfit.problem import VisibilityTable, build_problem, shadowed_views
from viewer.lighting.lightfit.reference import plane_reference
from viewer.lighting.lightfit.samples import all_texels, map_samples
from viewer.lighting.lightfit.settings import FitSettings
from viewer.lighting.lightfit.sphere_lobes import SphereView, sphere_reference, sphere_view
from viewer.lighting.lightfit.views import PlaneView, plane_view
from viewer.scene.area_lights import PAPER_TO_CAMERA, load_lights

HDRI = SHARED_DATA / "hdri"
SMALL = FitSettings(sphere_resolution=32, plane_resolution=48, shadow_resolution=64, samples=256)


@pytest.fixture(scope="module")
def rooitou():
    return load_envmap(HDRI / "rooitou_park_1k.hdr").downsampled(256)


def sky_and_sun(h=32, sun=1e6, row=6, col=40):
    px = np.full((h, 2 * h, 3), 0.2, np.float32)
    px[row, col] = sun
    return EnvMap(px, "synthetic sun")


def assert_sane(lights, n):
    assert len(lights) == n
    assert np.isfinite(lights.to_array()).all()
    assert (lights.intensity >= 0).all()
    assert (lights.sigma >= 0).all() and (lights.sigma <= 20).all()
    dots = lights.direction @ lights.direction.T
    np.fill_diagonal(dots, -1)
    assert np.degrees(np.arccos(np.clip(dots.max(), -1, 1))) > 0.5, "two lights collapsed onto one direction"


# ---------------------------------------------------------------- conventions
def test_paper_light_convention_maps_pixels_to_the_same_pixels():
    """The reference code's map frame (top row y = -1, t = pi (2u - 1), (cos p cos t, sin p, cos p sin t))
    and ours give the same pixel once PAPER_TO_CAMERA is applied."""
    h, w = 16, 32
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    t = np.pi * (2 * u[None, :] - 1)
    p = np.pi * (v[:, None] - 0.5)  # top row (v = 0) has y = sin(p) = -1
    paper = np.stack(np.broadcast_arrays(np.cos(p) * np.cos(t), np.sin(p), np.cos(p) * np.sin(t)), axis=-1)
    np.testing.assert_allclose(paper @ PAPER_TO_CAMERA.T, pixel_directions(h, w), atol=1e-12)


def test_published_paper_lights_import():
    lights = load_lights(SHARED_DATA / "als_040_blue_lagoon_night_2k.npy")
    assert len(lights) == 16
    raw = np.load(SHARED_DATA / "als_040_blue_lagoon_night_2k.npy")
    np.testing.assert_allclose(lights.sigma, raw[:, 3])
    np.testing.assert_allclose(lights.intensity, raw[:, 4:])
    # the paper's y points down: its brightest (night lamp) lights sit above our horizon
    brightest = np.argsort(lights.intensity.sum(axis=1))[-2:]
    assert (lights.direction[brightest, 1] > 0.3).all() and (raw[brightest, 1] < -0.3).all()


# ---------------------------------------------------------------- samples and reference
def test_samples_keep_the_energy_and_the_budget(rooitou):
    for budget in (64, 256, 1024):
        s = map_samples(rooitou, budget)
        assert len(s) <= budget
        np.testing.assert_allclose(s.energy(), rooitou.energy(), rtol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(s.direction, axis=1), 1.0, atol=1e-12)
    tiny = EnvMap(np.random.default_rng(0).random((4, 8, 3)).astype(np.float32))
    assert len(map_samples(tiny, 1024)) == 32  # smaller than the budget: every texel


def _subset_sphere(view: SphereView, step: int) -> SphereView:
    return SphereView(view.resolution, view.normal[::step], view.pixel_index[::step])


def _subset_plane(view: PlaneView, step: int) -> PlaneView:
    return PlaneView(view.name, view.scene, view.points[::step], view.normal[::step], view.on_object[::step],
                     view.plane_normal, view.occluder)


def test_reference_matches_the_brute_force_sum_over_every_texel():
    """The sampled reference (1024 samples of the 512-wide working map) against all 524 288 texels of
    the full 1k map, on the hard-sun map; the figures are quoted in docs/lights.md."""
    env = load_envmap(HDRI / "rooitou_park_1k.hdr")
    sphere = _subset_sphere(sphere_view(64), 61)
    plane = _subset_plane(plane_view("sphere", 96), 149)
    full, sampled = all_texels(env), map_samples(env, 1024)
    bd, bs = (torch.as_tensor(a) for a in sphere_reference(full, sphere.normal))
    sd, ss = (torch.as_tensor(a) for a in sphere_reference(sampled, sphere.normal))
    bp, sp = plane_reference(full, plane), plane_reference(sampled, plane)
    assert relative_l1(sd, bd) < 0.003
    assert relative_l1(ss, bs) < 0.01
    assert relative_l1(sp, bp) < 0.003


def test_analytic_shadow_of_the_sphere_from_straight_above():
    view = plane_view("sphere", 48)
    up = torch.as_tensor(view.plane_normal, dtype=torch.float32)[None]
    vis = view.visibility(up, slice(None))[:, 0].numpy()
    centre = view.occluder.center
    offset = view.points - centre
    horizontal = np.linalg.norm(offset - np.outer(offset @ view.plane_normal, view.plane_normal), axis=1)
    plane = ~view.on_object
    far, near = plane & (horizontal > 1.02), plane & (horizontal < 0.98)
    assert near.any() and far.any()
    assert (vis[far] == 1).all() and (vis[near] == 0).all()
    assert (vis[view.on_object] == 1).all()  # a point on the sphere sees straight up (n.l decides the rest)


def test_visibility_table_is_the_exact_csm_at_nodes_and_close_between(rooitou):
    problem = build_problem(rooitou, SMALL)
    dirs = np.array([[0.3, 0.8, 0.52], [-0.6, 0.6, 0.53]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    views = shadowed_views(problem.plane, dirs, problem.rotations, SMALL.shadow_resolution)
    grid = (0.0, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0)
    table = VisibilityTable.of(views, grid)
    torch.testing.assert_close(table(torch.tensor([2.0, 6.0])), views.soft_visibility(torch.tensor([2.0, 6.0])))
    between = torch.tensor([2.5, 7.0])
    err = (table(between) - views.soft_visibility(between)).abs()
    assert float(err.mean()) < 0.003 and float(err.max()) < 0.1


# ---------------------------------------------------------------- fitting: extreme maps
@pytest.mark.parametrize("method", ["fast", "median-cut"])
def test_hard_sun_map(rooitou, method):
    lights = fit_lights(rooitou, 8, method, SMALL)
    assert_sane(lights, 8)
    sun = int(np.argmax(lights.intensity.sum(axis=1)))
    lum = rooitou.pixels.sum(axis=2)
    true_sun = pixel_directions(*lum.shape)[np.unravel_index(lum.argmax(), lum.shape)]
    assert np.degrees(np.arccos(min(1.0, float(lights.direction[sun] @ true_sun)))) < 5.0
    if method == "fast":
        assert lights.sigma[sun] <= np.median(lights.sigma)  # a sun casts one of the sharper shadows


def test_one_texel_sun_a_million_times_the_sky():
    env = sky_and_sun()
    lights = fit_lights(env, 8, "fast", SMALL)
    assert_sane(lights, 8)
    sun_dir = pixel_directions(32, 64)[6, 40]
    best = int(np.argmax(lights.intensity.sum(axis=1)))
    assert np.degrees(np.arccos(np.clip(lights.direction[best] @ sun_dir, -1, 1))) < 3.0
    assert lights.intensity[best].sum() > 0.9 * lights.intensity.sum()


def test_black_map_gives_zero_intensities_and_a_warning():
    env = EnvMap(np.zeros((16, 32, 3), np.float32), "black.hdr")
    with pytest.warns(UserWarning, match="black"):
        lights = fit_lights(env, 4, "fast", SMALL)
    assert len(lights) == 4 and (lights.intensity == 0).all()


def test_constant_map_gives_equal_lights_and_small_error():
    env = EnvMap(np.full((32, 64, 3), 0.5, np.float32), "constant")
    lights = fit_lights(env, 16, "fast", SMALL)
    assert_sane(lights, 16)
    total = lights.intensity.sum(axis=1)
    assert total.max() / total.min() < 1.6
    problem = build_problem(env, SMALL)
    assert shading_errors(problem, lights)["sphere"] < 0.05  # 16 point-like lobes on a uniform sky


def test_map_lit_only_from_below():
    px = np.zeros((32, 64, 3), np.float32)
    px[20:, :] = 1.0
    px[26, 10] = 50.0
    lights = fit_lights(EnvMap(px, "below"), 8, "fast", SMALL)
    assert_sane(lights, 8)
    strong = lights.intensity.sum(axis=1) > 0.05 * lights.intensity.sum(axis=1).max()
    assert (lights.direction[strong, 1] < 0.1).all()


def test_fast_fit_is_no_worse_than_median_cut_and_improves_the_sphere(rooitou):
    problem = build_problem(rooitou, SMALL)
    heldout = held_out(problem)
    fast = shading_errors(problem, fit_lights(rooitou, 8, "fast", SMALL, problem=problem), heldout)
    init = shading_errors(problem, fit_lights(rooitou, 8, "median-cut", SMALL, problem=problem), heldout)
    assert fast["sphere"] < init["sphere"]
    assert fast["plane"] < init["plane"] * 1.05 and fast["heldout"] < init["heldout"] * 1.1
    assert max(fast.values()) < 0.2


def test_paper_method_full_schedule_on_a_small_problem():
    env = sky_and_sun(h=16, sun=200.0, row=4, col=10)
    lights = fit_lights(env, 4, "paper", FitSettings(sphere_resolution=16, plane_resolution=32,
                                                       shadow_resolution=32, samples=128))
    assert_sane(lights, 4)
    sun_dir = pixel_directions(16, 32)[4, 10]
    assert (lights.direction @ sun_dir).max() > 0.9


def test_rotating_the_map_rotates_the_fit(rooitou):
    yaw = 90.0
    turned = rooitou.rotated(yaw)
    fit_turned = fit_lights(turned, 8, "fast", SMALL)
    turned_fit = fit_lights(rooitou, 8, "fast", SMALL).rotated(yaw)
    problem = build_problem(turned, SMALL)
    a, b = shading_errors(problem, fit_turned), shading_errors(problem, turned_fit)
    for view in ("sphere", "plane"):
        assert abs(a[view] - b[view]) < 0.01 + 0.3 * max(a[view], b[view])
    da, sa = problem.sphere_shading(torch.as_tensor(fit_turned.direction), torch.as_tensor(fit_turned.intensity))
    db, sb = problem.sphere_shading(torch.as_tensor(turned_fit.direction), torch.as_tensor(turned_fit.intensity))
    assert relative_l1(da, db) < 0.05


# ---------------------------------------------------------------- cache
def test_cache_hits_survive_reencoding_and_misses_on_edits(tmp_path, rooitou):
    exr = save_envmap(tmp_path / "map.exr", rooitou)
    assert map_hash(load_envmap(exr)) == map_hash(rooitou)
    edited = rooitou.pixels.copy()
    edited[0, 0] += 1.0
    assert map_hash(EnvMap(edited)) != map_hash(rooitou)


def test_cache_stores_once_and_ctrl_c_leaves_nothing(tmp_path, monkeypatch):
    env = sky_and_sun(h=16, sun=100.0, row=4, col=10)
    cache = tmp_path / "cache"

    def interrupt(stage, done, total):
        if stage == "directions" and done == 5:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        lights_for_map(env, 4, "fast", directory=cache, progress=interrupt)
    assert not cache.exists() or not any(cache.iterdir())

    first, cached = lights_for_map(env, 4, "fast", directory=cache)
    assert not cached and cache_path(env, 4, "fast", cache).is_file()
    assert [p.name for p in cache.iterdir()] == [cache_path(env, 4, "fast", cache).name]
    import viewer.lighting.lightfit.fit as fit

    monkeypatch.setattr(fit, "fit_lights", lambda *a, **k: pytest.fail("refitted a cached map"))
    again, cached = lights_for_map(env, 4, "fast", directory=cache)
    assert cached
    np.testing.assert_allclose(again.to_array(), first.to_array(), rtol=1e-6)
    record = json.loads(cache_path(env, 4, "fast", cache).read_text())["fit"]
    assert record["method"] == "fast" and record["n"] == 4


def test_corrupt_cache_entry_is_refitted(tmp_path):
    env = sky_and_sun(h=16, sun=100.0, row=4, col=10)
    path = cache_path(env, 2, "median-cut", tmp_path)
    path.write_text("{ not json")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        lights, cached = lights_for_map(env, 2, "median-cut", directory=tmp_path)
    assert not cached and len(lights) == 2
    assert any("corrupt" in str(w.message) for w in caught)
    assert load_lights(path).to_array().shape == (2, 7)


@pytest.mark.parametrize("t_max, eta_min, steps", [(40, 0.0, 40), (5, 1e-3, 23)])  # annealed; periodic past t_max
def test_cosine_adam_matches_torch_optim_step_for_step(t_max, eta_min, steps):
    from viewer.lighting.lightfit.adam import CosineAdam

    start = torch.randn(7, 3, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    target = torch.randn(7, 3, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    ours = start.numpy().copy()
    theirs = start.clone().requires_grad_(True)
    opt = CosineAdam([ours], lr=0.3, betas=(0.5, 0.999), t_max=t_max, eta_min=eta_min)
    ref = torch.optim.Adam([theirs], lr=0.3, betas=(0.5, 0.999))
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(ref, T_max=t_max, eta_min=eta_min)
    for _ in range(steps):
        opt.step([4.0 * (ours - target.numpy()) ** 3])  # the gradient of sum((p - target)^4)
        ref.zero_grad()
        ((theirs - target) ** 4).sum().backward()
        ref.step()
        sched.step()
        assert opt.lr == pytest.approx(ref.param_groups[0]["lr"], rel=1e-9, abs=1e-12)
    np.testing.assert_allclose(ours, theirs.detach().numpy(), atol=1e-9)
    assert not np.allclose(ours, start.numpy(), atol=1e-2)  # it moved


def _random_lights(n, seed):
    rng = np.random.default_rng(seed)
    direction = rng.normal(size=(n, 3))
    direction[0] = [0.0, 0.0, -1.0]  # straight from behind: the half vector's floor
    direction[1] = [1.0, 0.0, 1e-4]  # grazing
    return direction / np.linalg.norm(direction, axis=1, keepdims=True), rng.uniform(0.1, 3.0, size=(n, 3))


def test_sphere_lobes_are_the_twins_in_values_and_slopes():
    """The default fits' numpy shading of the sphere equals the twin's (viewer.twin.brdf), and its
    slopes equal torch's autograd through the twin, lights from behind and grazing ones included."""
    from viewer.lighting.lightfit.sphere_lobes import STEP2_MATERIAL, SphereLobes
    from viewer.twin.brdf import diffuse_shading, specular_shading

    normal = sphere_view(24).normal
    direction, _ = _random_lights(40, 3)
    lobes = SphereLobes(normal, dtype=np.float64)
    diff, spec, ds_dc, ds_dlz = lobes.shading_and_slopes(direction)
    np.testing.assert_allclose(lobes.shading(direction)[1], spec)
    n = torch.as_tensor(normal)
    material = torch.full((len(normal),), STEP2_MATERIAL, dtype=torch.float64)
    light = torch.tensor(direction, requires_grad=True)
    twin_spec = specular_shading(n, light, material, material)
    np.testing.assert_allclose(diff, diffuse_shading(n, light).detach().numpy(), atol=1e-12)
    np.testing.assert_allclose(spec, twin_spec.detach().numpy(), rtol=1e-9, atol=1e-12)
    weights = torch.as_tensor(np.random.default_rng(4).random(spec.shape))
    (twin_spec * weights).sum().backward()
    ours = (weights.numpy() * ds_dc) @ normal
    ours[:, 2] += (weights.numpy() * ds_dlz).sum(axis=1)

    def tangent(g):  # the slopes along the unit sphere of directions (what a fit of unit directions moves)
        return g - direction * (g * direction).sum(axis=1, keepdims=True)

    np.testing.assert_allclose(tangent(ours), tangent(light.grad.numpy()), rtol=1e-6, atol=1e-9)


def test_sphere_fit_loss_and_gradient_are_torchs_autograd(rooitou):
    """The instant fit's hand-written gradient of the paper's sRGB L1 loss against torch's autograd of
    the torch loss (the paper's method's) on the same references."""
    from viewer.lighting.lightfit.paper import step2_loss

    problem = build_problem(rooitou, FitSettings(sphere_resolution=24, samples=256), shadows=False)
    direction, intensity = _random_lights(6, 5)
    loss, g_dir, g_int = problem.target.loss_and_gradient(direction, intensity)
    d = torch.tensor(direction, dtype=torch.float32, requires_grad=True)
    i = torch.tensor(intensity, dtype=torch.float32, requires_grad=True)
    ref = step2_loss(problem, d, i)
    ref.backward()
    assert loss == pytest.approx(float(ref.detach()), rel=1e-4)
    np.testing.assert_allclose(g_int, i.grad.numpy(), rtol=2e-3, atol=1e-6)
    def tangent(g):
        return g - direction * (g * direction).sum(axis=1, keepdims=True)

    np.testing.assert_allclose(tangent(g_dir), tangent(d.grad.numpy()), rtol=2e-3, atol=1e-5)


def test_the_default_fits_do_not_import_torch(tmp_path):
    """``relight fit-lights`` with the default method runs without torch (importing it alone costs about
    2 s here: docs/lights.md)."""
    import subprocess
    import sys

    code = ("import sys; from viewer.lighting.envmap import EnvMap; import numpy as np; "
            "from viewer.lighting.lightfit.fit import fit_lights; "
            "px = np.full((16, 32, 3), 0.2, np.float32); px[4, 9] = 500.0; "
            "lights = fit_lights(EnvMap(px, 'sun'), 4, 'instant'); lights = fit_lights(EnvMap(px, 'sun'), 4, 'fast'); "
            "print('torch' in sys.modules, len(lights))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.split() == ["False", "4"]
