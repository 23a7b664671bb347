"""Mitsuba ground truth of a scene bundle's own geometry (viewer/lab/data/reference.py)."""

from __future__ import annotations

import numpy as np
import pytest

from viewer.gl import Engine, EngineOptions
from viewer.lab.data.reference import envmap_emitter, mitsuba, render_bundle_reference
from viewer.lab.scenes import plane_and_box
from viewer.lighting.envmap import EnvMap, load_envmap, pixel_directions
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.area_lights import load_lights, rotation_matrix
from viewer.scene.bundle import load_scene
from viewer.scene.resampling import resample_scene


def test_envmap_frame_matches_the_project_convention():
    mi = mitsuba()
    h, w = 32, 64
    img = np.zeros((h, w, 3), np.float32)
    img[..., 0] = (np.arange(w)[None, :] + 0.5) / w
    img[..., 1] = (np.arange(h)[:, None] + 0.5) / h
    img[..., 2] = 1.0
    env = EnvMap(img)
    d = pixel_directions(h, w)
    rot = rotation_matrix(30.0, -20.0)
    emitter = mi.load_dict(envmap_emitter(mi, env, 30.0, -20.0))
    for i, j in [(5, 7), (16, 20), (25, 50), (10, 33), (20, 2)]:
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-(rot @ d[i, j])).tolist())  # the texel's direction after the turn
        got = np.array(emitter.eval(si)).ravel()
        assert abs(got[0] - img[i, j, 0]) < 1.0 / w and abs(got[1] - img[i, j, 1]) < 1.0 / h


def test_background_seen_through_the_camera_matches_mitsuba():
    """EnvMap.seen_through (the input photo's background in training) against Mitsuba's camera
    looking at the turned map with nothing in front of it."""
    from viewer.lab.data.reference import camera_sensor
    from viewer.scene.bundle import Scene
    from viewer.scene.camera import Camera

    mi = mitsuba()
    env = load_envmap(asset_dir() / "envmaps" / "studio_small_03_256.hdr")
    cam = Camera(48, 32)
    scene = Scene(albedo=np.zeros((32, 48, 3), np.float32), specular=np.zeros((32, 48), np.float32),
                  roughness=np.zeros((32, 48), np.float32), normal=np.zeros((32, 48, 3), np.float32),
                  depth=np.full((32, 48), 4.0, np.float32), mask=np.zeros((32, 48), bool), camera=cam)
    ours = env.seen_through(cam, 75.0, 10.0)
    img = np.array(mi.render(mi.load_dict({"type": "scene", "integrator": {"type": "direct"},
                                           "sensor": camera_sensor(mi, scene, 64), "light": envmap_emitter(mi, env, 75.0, 10.0)}),
                             spp=64), np.float32)[..., :3]
    rel = np.abs(img - ours).mean() / ours.mean()
    assert rel < 0.05, rel


def _unshadowed_diffuse(scene, env: EnvMap):
    small = env  # every texel (a blurred sun would misplace its light)
    h, w = small.pixels.shape[:2]
    d = pixel_directions(h, w).reshape(-1, 3)
    omega = (2 * np.pi / w) * (np.cos(np.pi * np.arange(h) / h) - np.cos(np.pi * (np.arange(h) + 1) / h))
    radiance = (small.pixels * omega[:, None, None]).reshape(-1, 3)
    n = scene.normal[scene.mask].astype(np.float64)
    return np.clip(n @ d.T, 0, None) @ radiance / np.pi


def test_shadowed_diffuse_shading_never_exceeds_the_unshadowed():
    scene = plane_and_box(64)
    env = load_envmap(asset_dir() / "envmaps/immenstadter_horn_256.hdr")
    ref = render_bundle_reference(scene, env, spp=1024)
    inner = scene.mask.copy()
    inner[:2], inner[-2:], inner[:, :2], inner[:, -2:] = False, False, False, False  # pixel coverage < 1 at the border
    unshadowed = np.zeros(scene.mask.shape + (3,))
    unshadowed[scene.mask] = _unshadowed_diffuse(scene, env)
    # 4 x 4 pixel blocks inside the border: Monte Carlo noise (a few % per pixel at 1024 spp) averages out
    def blocks(img):
        return img[2:62, 2:62].mean(-1).reshape(15, 4, 15, 4).mean(axis=(1, 3))

    ratio = blocks(ref["diffuse_shadowed"]) / blocks(unshadowed)
    assert ratio.max() < 1.03  # never more light than the unshadowed integral
    assert ratio.min() < 0.8  # the box does shadow the plane
    # far from the box the plane sees the whole upper hemisphere: shadowed = unshadowed
    assert np.median(ratio) == pytest.approx(1.0, abs=0.02)
    # the mesh covers its pixels, except pixel-wide slits where a depth gap splits it (box rim)
    assert np.median(ref["coverage"][inner]) == 1.0 and (ref["coverage"][inner] < 0.99).mean() < 0.05


def test_engine_against_the_reference_on_the_sample(ctx):
    """The engine's 16 fitted lights against the full map, ray traced: the error the engine makes
    (lights, shadow maps, CSM, Lambert vs Disney diffuse) inside the figure's silhouette."""
    scene = resample_scene(load_scene(sample_scene_dir()), 128)
    env = load_envmap(asset_dir() / "envmaps/immenstadter_horn_256.hdr")
    lights = load_lights(asset_dir() / "envmaps/immenstadter_horn_256.lights.json")
    ref = render_bundle_reference(scene, env, yaw=180.0, spp=64)
    eng = Engine(ctx, scene, EngineOptions())
    eng.set_lights(lights.rotated(180.0))
    eng.render()
    hdr = eng.output.read_hdr()
    eng.release()
    inner = scene.mask & (ref["coverage"] > 0.999)
    err = np.abs(hdr - ref["full"])[inner].sum() / ref["full"][inner].sum()
    assert err < 0.15
    assert hdr[inner].mean() == pytest.approx(ref["full"][inner].mean(), rel=0.1)
