"""The spherical-harmonics baseline's lighting against exact irradiance."""

from __future__ import annotations

import numpy as np

from viewer.lighting.envmap import EnvMap, pixel_directions, solid_angles
from viewer.lighting.sh import irradiance, project, relight


def _exact_irradiance(env: EnvMap, normals):
    d = pixel_directions(env.height, env.width).reshape(-1, 3)
    w = (solid_angles(env.height, env.width)[:, None] * np.ones((1, env.width))).reshape(-1)
    cos = np.clip(normals @ d.T, 0, None)
    return cos @ (env.pixels.reshape(-1, 3) * w[:, None])


def test_constant_sky_gives_pi():
    env = EnvMap(np.ones((32, 64, 3), np.float32))
    n = np.array([[0, 0, 1.0], [0, 1.0, 0], [0.6, 0, -0.8]])
    assert np.allclose(irradiance(project(env), n), np.pi, rtol=1e-3)
    img = relight(np.full((1, 3, 3), 0.5, np.float32), n[None].astype(np.float32), np.ones((1, 3), bool), env)
    assert np.allclose(img, 0.5, rtol=1e-3)


def test_smooth_sky_is_close_to_exact():
    h, w = 32, 64
    d = pixel_directions(h, w)
    sky = np.clip(d[..., 1:2], 0, None) * np.array([0.4, 0.6, 1.0]) + 0.05  # a bright zenith
    env = EnvMap(sky.astype(np.float32))
    rng = np.random.default_rng(0)
    n = rng.normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    exact = _exact_irradiance(env, n)
    approx = irradiance(project(env), n)
    assert np.abs(approx - exact).mean() < 0.05 * exact.mean()  # order 2 holds ~all of a smooth sky
