"""The torch twin (viewer/twin): shading, shadow maps, convolutional shadow maps, composite, gradients."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from viewer.lab.scenes import plane_and_box
from viewer.scene import shadow_space
from viewer.scene.area_lights import AreaLights
from viewer.scene.bundle import Scene
from viewer.scene.camera import Camera
from viewer.scene.depth_mesh import caster_points, depth_mesh
from viewer.twin import (
    LightTensors,
    SceneTensors,
    diffuse_shading,
    gaussian_filter,
    light_frames,
    project_vertices,
    rasterize_depth,
    receiver_coordinates,
    render,
    sample_bilinear,
    specular_shading,
)

PLANE_DEPTH = 4.0
BOX_DEPTH = 3.0
BOX_HALF = 0.3


def make_scene(size: int = 64, box: bool = True, albedo: float = 0.5, specular: float = 0.5,
               roughness: float = 0.5) -> Scene:
    """A plane facing the camera at PLANE_DEPTH, optionally with the front face of a box (a square of
    half-width BOX_HALF at BOX_DEPTH) in front of it; the whole image is masked."""
    return plane_and_box(size, box, albedo, specular, roughness, PLANE_DEPTH, BOX_DEPTH, BOX_HALF)


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def lights(direction, sigma, intensity=1.0, requires_grad=False) -> LightTensors:
    d = torch.tensor(unit(direction), dtype=torch.float32)
    s = torch.tensor(np.broadcast_to(np.asarray(sigma, np.float32), (len(d),)).copy())
    i = torch.tensor(np.broadcast_to(np.asarray(intensity, np.float32), (len(d), 3)).copy())
    return LightTensors(*(t.requires_grad_(requires_grad) for t in (d, s, i)))


# ------------------------------------------------------------------------------------------- BRDF
def numpy_shading(n, l, spec, rough):
    """Direct float64 evaluation of docs/conventions.md for one normal and one light."""
    nl, nv = float(n @ l), float(n[2])
    diffuse = max(nl, 0.0) / math.pi
    if nl <= 0 or nv <= 0 or spec <= 0:
        return diffuse, 0.0
    h = (l + np.array([0.0, 0.0, 1.0])) / np.linalg.norm(l + np.array([0.0, 0.0, 1.0]))
    nh, lh = max(float(n @ h), 0.0), max(float(l @ h), 0.0)
    alpha = max(rough * rough, 1e-3)
    a2 = alpha * alpha
    f0 = 0.08 * spec
    fresnel = f0 + (1 - f0) * (1 - lh) ** 5
    d = a2 / (math.pi * (nh * nh * (a2 - 1) + 1) ** 2)

    def g1(x):
        return 1.0 / (x + math.sqrt(a2 + x * x - a2 * x * x))

    return diffuse, nl * fresnel * d * g1(nl) * g1(nv)


def test_shading_matches_direct_formula():
    rng = np.random.default_rng(0)
    normals = unit(rng.normal(size=(5, 7, 3)) + [0.0, 0.0, 1.5]).reshape(5, 7, 3)
    spec = rng.uniform(0.0, 1.0, (5, 7))
    spec[0, :3] = 0.0
    rough = rng.uniform(0.0, 1.0, (5, 7))
    rough[1, 0], rough[1, 1] = 0.0, 1.0
    dirs = unit([[0.2, 0.3, 1.0], [-0.7, 0.1, 0.4], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.1, -0.9, 0.2]])
    t = lambda a: torch.tensor(a, dtype=torch.float32)  # noqa: E731
    diff = diffuse_shading(t(normals), t(dirs)).numpy()
    spc = specular_shading(t(normals), t(dirs), t(spec), t(rough)).numpy()
    assert diff.shape == spc.shape == (5, 5, 7)
    for li in range(5):
        for i in range(5):
            for j in range(7):
                d_ref, s_ref = numpy_shading(normals[i, j], dirs[li], spec[i, j], rough[i, j])
                assert diff[li, i, j] == pytest.approx(d_ref, rel=1e-5, abs=1e-7)
                assert spc[li, i, j] == pytest.approx(s_ref, rel=2e-4, abs=1e-6)


@pytest.mark.parametrize("rough", [0.0, 1.0])
def test_shading_stiff_cases_finite(rough):
    """Roughness 0 and 1, the mirror direction, grazing, below-horizon and from-behind lights."""
    n = torch.tensor([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, 0.0, 1.0]])
    dirs = torch.tensor(unit([[0, 0, 1], [1, 0, 0], [0, 0, -1], [0, 1, -1e-7], [0.96, 0, 0.28]]),
                        dtype=torch.float32, requires_grad=True)
    s = specular_shading(n, dirs, torch.full((3,), 0.7), torch.full((3,), rough))
    d = diffuse_shading(n, dirs)
    assert torch.isfinite(s).all() and torch.isfinite(d).all()
    assert (s[2] == 0).all() and (d[2] == 0).all()  # from behind
    (s.sum() + d.sum()).backward()
    assert torch.isfinite(dirs.grad).all()


# ------------------------------------------------------------------------------------ frames
DIRECTIONS = unit([[0.3, 0.2, 1.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.05], [0.05, 0.99, 0.1], [-0.2, -0.95, 0.3],
                   [0.0, 0.0, -1.0]])


def test_receiver_coordinates_match_numpy_rule():
    scene = make_scene(32)
    pts = caster_points(scene, depth_mesh(scene))
    rng = np.random.default_rng(1)
    normals = unit(rng.normal(size=(len(pts), 3)))
    res = 128
    frames_np = shadow_space.light_frames(pts, DIRECTIONS, res)
    t_dirs = torch.tensor(DIRECTIONS, dtype=torch.float64, requires_grad=True)
    frames = light_frames(torch.tensor(pts, dtype=torch.float64), t_dirs, res)
    u, v, d, bias = receiver_coordinates(torch.tensor(pts, dtype=torch.float64),
                                         torch.tensor(normals, dtype=torch.float64), frames, res)
    for i, f in enumerate(frames_np):
        # (the numpy rule projects the points in float32 for the depth range: 1e-6 agreement)
        np.testing.assert_allclose(frames.matrix()[i].detach().numpy(), f.matrix, atol=1e-6)
        assert frames.empty_depth == pytest.approx(f.empty_depth)
        ref = shadow_space.receiver_coordinates(pts, normals, f, res)
        for got, want in zip((u, v, d, bias), ref):
            np.testing.assert_allclose(got[i].detach().numpy(), want, atol=1e-6)
    # float32, as render() uses it
    frames32 = light_frames(torch.tensor(pts), t_dirs.float(), res)
    got32 = receiver_coordinates(torch.tensor(pts), torch.tensor(normals, dtype=torch.float32), frames32, res)
    for i, f in enumerate(frames_np):
        ref = shadow_space.receiver_coordinates(pts, normals, f, res)
        for got, want in zip(got32, ref):
            np.testing.assert_allclose(got[i].detach().numpy(), want, atol=2e-5)
    (u.sum() + v.sum() + d.sum() + bias.sum()).backward()
    assert torch.isfinite(t_dirs.grad).all() and (t_dirs.grad != 0).any()


# ------------------------------------------------------------------------------------ rasterizer
def brute_force_shadow_map(uvz: np.ndarray, triangles: np.ndarray, res: int, empty: float) -> np.ndarray:
    """Per-texel float64 reference: minimum interpolated z of the triangles containing the centre,
    with the same top-left tie rule on edges."""
    out = np.full((res, res), empty)
    y, x = np.mgrid[0:res, 0:res] + 0.5
    for tri in triangles:
        p = uvz[tri, :2] * res
        z = uvz[tri, 2]
        area = (p[1, 0] - p[0, 0]) * (p[2, 1] - p[0, 1]) - (p[2, 0] - p[0, 0]) * (p[1, 1] - p[0, 1])
        if area == 0:
            continue
        inside = np.ones((res, res), bool)
        lam = []
        for e in range(3):
            a, b = p[e], p[(e + 1) % 3]
            w = np.sign(area) * ((b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]))
            ga, gb = np.sign(area) * (a[1] - b[1]), np.sign(area) * (b[0] - a[0])  # inward normal
            own = ga > 0 or (ga == 0 and gb > 0)
            inside &= (w > 0) | ((w == 0) & own)
            lam.append(w / abs(area))  # barycentric of the vertex opposite this edge
        depth = lam[1] * z[0] + lam[2] * z[1] + lam[0] * z[2]
        out = np.where(inside, np.minimum(out, depth), out)
    return out


def test_rasterizer_matches_brute_force():
    rng = np.random.default_rng(2)
    size = 24
    cam = Camera(size, size)
    yy, xx = np.mgrid[0:size, 0:size]
    depth = (4.0 - 0.6 * np.exp(-((xx - 11.3) ** 2 + (yy - 12.7) ** 2) / 40.0) + 0.01 * rng.normal(size=(size, size)))
    mask = (xx - 12) ** 2 + (yy - 12) ** 2 < 11.5 ** 2
    scene = Scene(albedo=np.ones((size, size, 3), np.float32), specular=np.zeros((size, size), np.float32),
                  roughness=np.ones((size, size), np.float32),
                  normal=np.broadcast_to(np.float32([0, 0, 1]), (size, size, 3)).copy(),
                  depth=depth.astype(np.float32), mask=mask, camera=cam).validate()
    mesh = depth_mesh(scene, step=1)
    # random triangles on top: overlapping, slivers, some partly outside the map
    extra_v = mesh.vertices[mesh.triangles[rng.integers(0, mesh.n_triangles, 20)].ravel()] + rng.normal(
        scale=0.15, size=(60, 3)).astype(np.float32)
    vertices = np.concatenate([mesh.vertices, extra_v]).astype(np.float32)
    triangles = np.concatenate([mesh.triangles, len(mesh.vertices) + np.arange(60).reshape(20, 3)]).astype(np.int32)
    res = 40
    frames = light_frames(torch.tensor(caster_points(scene, depth_mesh(scene))), torch.tensor(DIRECTIONS[:4], dtype=torch.float32), 256)
    uvz = project_vertices(torch.tensor(vertices), frames)
    got = rasterize_depth(uvz, torch.tensor(triangles), res, frames.empty_depth).numpy()
    for i in range(len(frames)):
        want = brute_force_shadow_map(uvz[i].double().numpy(), triangles, res, frames.empty_depth)
        differs = np.abs(got[i] - want) > 1e-5
        assert differs.sum() <= 3, f"light {i}: {differs.sum()} texels differ"
        assert (want < frames.empty_depth).sum() > 100  # the mesh covers a good part of the map


def test_rasterizer_is_watertight_on_a_grid():
    """A regular grid whose edges pass exactly through texel centres: no holes, no leaks."""
    res, n = 32, 9
    g = np.linspace(0.5 / res, 1 - 0.5 / res, n)
    uu, vv = np.meshgrid(g, g)
    uvz = np.stack([uu, vv, 0.25 + 0.5 * uu], -1).reshape(-1, 3)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    tris = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    got = rasterize_depth(torch.tensor(uvz, dtype=torch.float32)[None], torch.tensor(tris), res, 1.0)[0].numpy()
    want = brute_force_shadow_map(uvz, tris, res, 1.0)
    covered = want < 1.0
    # the grid's border runs through texel centres: its left and top (v = 0) edges own them, the
    # right and bottom ones do not
    assert covered[:-1, :-1].all() and not covered[-1].any() and not covered[:, -1].any()
    np.testing.assert_allclose(got, want, atol=1e-6)


# ------------------------------------------------------------------------------------ CSM
def direct_gaussian(maps: torch.Tensor, sigma_px: float) -> torch.Tensor:
    r = int(math.ceil(3 * sigma_px))
    t = torch.arange(-r, r + 1, dtype=torch.float64)
    w = torch.exp(-0.5 * (t / sigma_px) ** 2)
    w = w / w.sum()
    c = maps.shape[1]
    x = F.pad(maps, (r, r, r, r), mode="replicate")
    x = F.conv2d(x, w.view(1, 1, 1, -1).repeat(c, 1, 1, 1), groups=c)
    return F.conv2d(x, w.view(1, 1, -1, 1).repeat(c, 1, 1, 1), groups=c)


def test_gaussian_filter_is_replicate_padded_gaussian():
    maps = torch.rand(3, 4, 20, 20, dtype=torch.float64)
    sigmas = [0.0, 1.3, 9.0]  # 9 texels: the kernel is wider than the map
    got = gaussian_filter(maps, torch.tensor(sigmas, dtype=torch.float64))
    torch.testing.assert_close(got[0], maps[0], atol=1e-12, rtol=0)
    for i in (1, 2):
        torch.testing.assert_close(got[i:i + 1], direct_gaussian(maps[i:i + 1], sigmas[i]), atol=1e-10, rtol=0)


def test_bilinear_sampling_convention():
    res = 8
    maps = torch.arange(res * res, dtype=torch.float32).reshape(1, 1, res, res)
    u = torch.tensor([[(3 + 0.5) / res, (3 + 1.0) / res, 0.0]])
    v = torch.tensor([[(5 + 0.5) / res, (5 + 0.5) / res, 1.0]])
    got = sample_bilinear(maps, u, v)[0, 0]
    torch.testing.assert_close(got, torch.tensor([5 * res + 3, 5 * res + 3.5, (res - 1) * res]))


# ------------------------------------------------------------------------------------ render
SHADOW_DIR = unit([0.35, 0.25, 1.0])


def expected_hard_shadow(scene: Scene, direction: np.ndarray) -> np.ndarray:
    """Plane pixels from which a ray towards the light meets the box face (the mesh's square between
    the box pixels' centres)."""
    pts = scene.points()
    box = scene.depth < 0.5 * (BOX_DEPTH + PLANE_DEPTH)
    lo, hi = pts[box][:, :2].min(axis=0), pts[box][:, :2].max(axis=0)
    t = (PLANE_DEPTH - BOX_DEPTH) / direction[2]
    q = pts[..., :2] + t * direction[:2]
    return ~box & (q >= lo).all(axis=-1) & (q <= hi).all(axis=-1)


def test_box_casts_its_silhouette_as_hard_shadow():
    scene = make_scene(96)
    out = render(scene, lights(SHADOW_DIR, 0.0), shadow_resolution=256, shadow_step=1)
    shadow = out.hard_visibility[0].numpy() < 0.5
    want = expected_hard_shadow(scene, SHADOW_DIR[0])
    assert want.sum() > 150
    perimeter = (want ^ np.roll(want, 1, 0)).sum() + (want ^ np.roll(want, 1, 1)).sum()
    assert abs(int(shadow.sum()) - int(want.sum())) <= 0.5 * perimeter
    assert (shadow ^ want).sum() <= perimeter
    # the shadow maps hold the box nearer the light than the plane
    assert out.shadow_maps.shape == (1, 256, 256)


def gradient_energy(img: np.ndarray) -> float:
    """Sum of squared finite differences: blurring an edge lowers it (total variation would not move)."""
    return float((np.diff(img, axis=0) ** 2).sum() + (np.diff(img, axis=1) ** 2).sum())


def test_soft_visibility_hard_at_zero_sigma_and_smoother_with_sigma():
    scene = SceneTensors.from_scene(make_scene(96), shadow_step=1)
    sigmas = [0.0, 1.0, 2.0, 4.0, 8.0]
    out = render(scene, lights(np.repeat(SHADOW_DIR, len(sigmas), 0), sigmas), shadow_resolution=256)
    soft, hard = out.soft_visibility.numpy(), out.hard_visibility.numpy()
    assert np.abs(soft[0] - hard[0]).mean() < 0.02
    energy = [gradient_energy(s) for s in soft]
    assert all(a > b for a, b in zip(energy, energy[1:])), energy
    assert np.abs(soft[-1] - hard[-1]).mean() > np.abs(soft[0] - hard[0]).mean()


def test_gradients_reach_every_light_parameter():
    scene = make_scene(64)
    lt = lights(unit([[0.35, 0.25, 1.0], [-0.5, 0.1, 0.8]]), [3.0, 6.0], [[1.0, 0.9, 0.8], [0.3, 0.4, 0.5]],
                requires_grad=True)
    out = render(scene, lt, shadow_resolution=128, shadow_step=1)
    out.image.mean().backward()
    for name in ("direction", "sigma", "intensity"):
        g = getattr(lt, name).grad
        assert g is not None and torch.isfinite(g).all(), name
        assert (g.reshape(2, -1).abs().sum(dim=1) > 0).all(), name


def test_white_lambertian_energy():
    """A white Lambertian plane (and the box face in front of it, which keeps the shadow maps' depth
    range from collapsing) under a unit light facing it: exactly 1/pi everywhere, never more."""
    scene = make_scene(48, albedo=1.0, specular=0.0)
    for sigma in (0.0, 2.0, 8.0):
        out = render(scene, lights([0.0, 0.0, 1.0], sigma), shadow_resolution=128, shadow_step=1)
        torch.testing.assert_close(out.image, torch.full_like(out.image, 1.0 / math.pi), atol=1e-7, rtol=0)
    rng = np.random.default_rng(3)
    dirs = np.concatenate([unit(rng.normal(size=(12, 3))), unit([[1, 0, 0], [0, 1, 0.01], [0, 0, -1]])])
    out = render(scene, lights(dirs, rng.uniform(0, 10, len(dirs))), shadow_resolution=128, shadow_step=1)
    per_light = out.soft_visibility * out.diffuse
    assert float(per_light.max()) <= 1.0 / math.pi + 1e-7
    assert float(out.image.max()) <= len(dirs) / math.pi


def test_stiff_light_parameters_stay_finite():
    scene = make_scene(48, roughness=0.0)
    scene.roughness[:24] = 1.0
    dirs = unit([[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, -1, 1e-4], [0.3, 0.2, 1.0], [0.3, 0.2, 1.0]])
    lt = lights(dirs, [0.0, 50.0, 0.0, 50.0, 0.0, 50.0], [[1e-6] * 3, [1e5] * 3, [1e5] * 3, [1e-6] * 3, [1e5] * 3,
                                                          [1e-6] * 3], requires_grad=True)
    out = render(scene, lt, shadow_resolution=128, shadow_step=1)
    for name in ("hard_visibility", "soft_visibility", "diffuse", "specular", "image"):
        assert torch.isfinite(getattr(out, name)).all(), name
    out.image.sum().backward()
    for name in ("direction", "sigma", "intensity"):
        assert torch.isfinite(getattr(lt, name).grad).all(), name


def test_area_lights_and_tensors_render_alike():
    scene = make_scene(32)
    al = AreaLights(unit([[0.3, 0.2, 1.0], [-0.4, 0.5, 0.7]]), [1.0, 4.0], [[1, 1, 1], [2, 1, 0.5]]).validate()
    a = render(scene, al, shadow_resolution=64, shadow_step=1)
    b = render(scene, (torch.tensor(al.direction), torch.tensor(al.sigma), torch.tensor(al.intensity)),
               shadow_resolution=64, shadow_step=1)
    torch.testing.assert_close(a.image, b.image)
    assert a.image.shape == (32, 32, 3) and a.soft_visibility.shape == (2, 32, 32)


DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


@pytest.mark.parametrize("device", DEVICES)
def test_device_matches_cpu(device):
    """Every device this machine has (CUDA where lent) renders what the CPU renders."""
    scene = make_scene(64)
    lt = lights(unit([[0.35, 0.25, 1.0], [-0.5, 0.1, 0.8]]), [0.0, 4.0], [[1.0, 0.9, 0.8], [0.3, 0.4, 0.5]])
    cpu = render(scene, lt, shadow_resolution=128, shadow_step=1)
    other = render(scene, LightTensors(*(t.to(device) for t in (lt.direction, lt.sigma, lt.intensity))),
                   shadow_resolution=128, shadow_step=1, device=device)
    assert other.image.device.type == device
    torch.testing.assert_close(other.shadow_maps.cpu(), cpu.shadow_maps, atol=1e-5, rtol=0)
    assert (other.hard_visibility.cpu() != cpu.hard_visibility).sum() <= 4
    torch.testing.assert_close(other.image.cpu(), cpu.image, atol=1e-3, rtol=1e-3)
