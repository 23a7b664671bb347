"""The viewer's session (engines, preview, lights) and light jobs, without a window."""

from __future__ import annotations

import numpy as np

from viewer.app.jobs import LightJob
from viewer.app.preview import FRAME_BUDGET_MS, PREVIEW_LEVELS, SAMPLES, START_LEVEL, PreviewPace
from viewer.app.session import Session
from viewer.gl import Engine, EngineOptions
from viewer.lighting.envmap import load_envmap
from viewer.lighting.map_lights import sidecar_lights
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.area_lights import load_lights
from viewer.scene.bundle import load_scene
from viewer.scene.look import Look

MAPS = asset_dir() / "envmaps"


def test_session_final_and_preview(ctx):
    scene = load_scene(sample_scene_dir())
    lights = load_lights(MAPS / "immenstadter_horn_256.lights.json")
    env = load_envmap(MAPS / "immenstadter_horn_256.hdr").pixels
    s = Session(ctx, scene, lights, env)
    s.update(yaw=150.0, exposure=0.5)
    s.set_sigma(0, 12.0)
    final = s.render(preview=False)
    ref = Engine(ctx, scene, EngineOptions())
    ref.set_environment(env)
    ref.set_lights(lights.with_sigma(0, 12.0))
    ref.set_look(Look(yaw=150.0, exposure=0.5))
    ref.render()
    np.testing.assert_array_equal(final.output.read_display(), ref.output.read_display())
    ref.release()
    preview = s.render(preview=True)
    assert preview is not final and preview.scene.width == PREVIEW_LEVELS[START_LEVEL].work
    assert preview.kit.counters["csm_basis"] == 0 and preview.kit.counters["shadow_map"] > 0  # hard shadows while dragging
    # shading and inspection views and switches go to the same engines
    s.update(view="albedo")
    shown = s.render().output.read_display()
    m = scene.mask
    assert np.abs(shown[m].astype(np.float32) / 255 - np.clip(scene.albedo[m], 0, 1) ** (1 / 2.2)).mean() < 0.02
    # new lights (another map): the sliders restart from their sigmas, a shadow view of a light
    # that no longer exists falls back to the relit image
    s.update(view="shadow", light=15)
    few = load_lights(MAPS / "studio_small_03_256.lights.json")
    few = type(few)(few.direction[:4], few.sigma[:4], few.intensity[:4])
    s.set_lights(few, environment=load_envmap(MAPS / "studio_small_03_256.hdr").pixels)
    assert s.look.view == "final" and len(s.sigma) == 4
    np.testing.assert_array_equal(s.sigma, few.sigma)
    s.render()
    s.release()


def test_light_jobs(tmp_path, monkeypatch):
    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache"))
    studio = MAPS / "studio_small_03_256.hdr"
    env = load_envmap(studio)
    assert sidecar_lights(env, studio, 16, "fast") is not None
    assert sidecar_lights(env, studio, 8, "fast") is None and sidecar_lights(env, studio, 16, "paper") is None
    import json
    import shutil

    old = shutil.copyfile(studio, tmp_path / studio.name)  # lights fitted before the fitters last changed
    record = json.loads(studio.with_suffix(".lights.json").read_text())
    record["fit"].pop("version")
    old.with_suffix(".lights.json").write_text(json.dumps(record))
    assert sidecar_lights(env, old, 16, "fast") is None
    job = LightJob(studio, 16, "fast")
    job._thread.join(60)
    assert job.done and job.error is None and job.result.how == "bundled" and len(job.result.lights) == 16
    missing = LightJob(tmp_path / "nope.hdr", 16, "fast")
    missing._thread.join(60)
    assert missing.result is None and "nope.hdr" in missing.error
    bad = tmp_path / "bad.hdr"
    bad.write_bytes(b"not an hdr")
    broken = LightJob(bad, 16, "fast")
    broken._thread.join(60)
    assert broken.result is None and "bad.hdr" in broken.error


def test_refined_shadows_arrive_when_the_lighting_stops(ctx, tiny_networks):
    """The refined mode shows the soft visibility, refines on a thread, and uses the result only for
    the lighting it was computed for."""
    import time

    from viewer.photo.refinement import Refiner
    from viewer.scene.resampling import resample_scene

    scene = resample_scene(load_scene(sample_scene_dir()), 96)
    s = Session(ctx, scene, load_lights(MAPS / "venice_sunset_256.lights.json"), None, EngineOptions(shadow_resolution=256))
    woken = []
    s.wake = lambda: woken.append(1)
    s.refined.refiner = Refiner(tiny_networks / "refine.safetensors")
    s.update(shadows="refined")
    soft_shown = s.render().output.read_hdr().copy()
    assert s.refining and not s.final.refined_current
    preview = s.render(preview=True)
    assert preview.kit.counters["csm_basis"] == 0  # hard shadows while dragging, no refinement
    deadline = time.time() + 60
    while not s.refined.job.done and time.time() < deadline:
        time.sleep(0.05)
    assert woken and s.poll_refinement() and s.final.refined_current
    refined = s.render().output.read_hdr()
    assert np.all(np.isfinite(refined)) and not np.array_equal(refined, soft_shown)
    # a job for a lighting that has since moved is dropped; the new lighting gets its own
    s.update(yaw=40.0)
    s.render()
    old = s.refined.job
    while not old.done:
        time.sleep(0.05)
    s.final.set_lights(s.lights.rotated(80.0))  # the lights moved on before the result was polled
    assert not s.poll_refinement() and not s.final.refined_current
    s.render()
    assert s.refining and s.refined.job is not old
    s.release()  # stops the running job at its next batch: a thread left inside torch aborts the exit
    assert s.refined.job.done


def test_the_preview_is_the_final_picture_coarser(ctx, tmp_path):
    """While the lighting is dragged the window shows the preview engine's frame: it differs from the
    full-quality frame of the same look only in resolution and shadow softness (issue 45): the same
    backdrop, exposure and horizon. Both downsampled to the preview's size, per pixel (0-255)."""
    import cv2

    from viewer.photo.inference import cached_bundle
    from viewer.scene.area_lights import facing_yaw
    from viewer.scene.resampling import load_sized_scene

    bundle, _ = cached_bundle(asset_dir() / "photos" / "underpass.jpg", max_size=768, ctx=ctx, bundles=tmp_path)
    scene = load_sized_scene(bundle, None, 768)
    lights = load_lights(MAPS / "immenstadter_horn_256.lights.json")
    s = Session(ctx, scene, lights, load_envmap(MAPS / "immenstadter_horn_256.hdr").pixels)
    s.update(yaw=facing_yaw(lights) + 20.0, exposure=0.5)
    final = s.render(preview=False).output.read_display().astype(np.float32)
    for level in range(len(PREVIEW_LEVELS)):  # every level the window's pace may pick
        s.preview_level = level
        preview = s.render(preview=True).output.read_display().astype(np.float32)
        h, w = preview.shape[:2]
        small = cv2.resize(final, (w, h), interpolation=cv2.INTER_AREA)
        alpha = cv2.resize(scene.frame.alpha, (w, h), interpolation=cv2.INTER_AREA)
        error = np.abs(small - preview).mean(axis=-1)
        assert error[alpha < 0.01].mean() < 1.5  # the backdrop: the same map, blur, exposure and horizon
        assert abs(float(small[alpha < 0.01].mean() - preview[alpha < 0.01].mean())) < 0.5  # not darker
        assert error.mean() < 2.5  # the person: finer and softer shadows in the final frame, nothing else


def test_the_drag_preview_paces_itself_to_the_frame_budget():
    """Slower frames than the budget: one level coarser after SAMPLES of them (never past the
    coarsest); a drag that had room: the next one starts a level finer; noise in one frame moves nothing."""
    pace = PreviewPace()
    assert pace.level == START_LEVEL
    pace.start_drag()
    for _ in range(SAMPLES):
        pace.record(2.0 * FRAME_BUDGET_MS)
    assert pace.level == START_LEVEL + 1
    for _ in range(10 * SAMPLES):
        pace.record(2.0 * FRAME_BUDGET_MS)
    assert pace.level == len(PREVIEW_LEVELS) - 1
    for ms in (0.3, 3.0, 0.3):  # one slow frame among fast ones: the median stays under the budget
        pace.record(ms * FRAME_BUDGET_MS)
    assert pace.level == len(PREVIEW_LEVELS) - 1
    pace.start_drag()  # the last drag's frames took 0.3 of the budget: room for a finer level
    assert pace.level == len(PREVIEW_LEVELS) - 2
    for _ in range(SAMPLES):
        pace.record(0.7 * FRAME_BUDGET_MS)  # fits, but no room for another step
    pace.start_drag()
    assert pace.level == len(PREVIEW_LEVELS) - 2
    for _ in range(SAMPLES):
        pace.record(0.2 * FRAME_BUDGET_MS)
    for _ in range(len(PREVIEW_LEVELS)):
        pace.start_drag()
        for _ in range(SAMPLES):
            pace.record(0.2 * FRAME_BUDGET_MS)
    assert pace.level == 0
    pace.start_drag()
    assert pace.level == 0


def test_preview_engines_are_kept_for_the_level_and_its_neighbours(ctx):
    scene = load_scene(sample_scene_dir())
    lights = load_lights(MAPS / "immenstadter_horn_256.lights.json")
    s = Session(ctx, scene, lights, load_envmap(MAPS / "immenstadter_horn_256.hdr").pixels)
    s.preview_level = 1
    made = 0
    while s.warm_preview():
        made += 1
    assert made == 9 and sorted(s.previews.engines) == [0, 1, 2]  # made, given the map, drawn: a step per idle frame
    assert all(e.complete for e in s.previews.engines.values())  # each drawn once: its first dragged frame pays nothing
    s.preview_level = 3
    assert s.warm_preview() and sorted(s.previews.engines) == [2, 3]  # far levels released, the new ones made
    assert s.warm_preview() and s.warm_preview() and not s.warm_preview()
    s.set_lights(s.base_lights, load_envmap(MAPS / "venice_sunset_256.hdr").pixels, new_map=True)
    for _ in range(4):  # the new map: each neighbour given it, then drawn
        assert s.warm_preview()
    assert not s.warm_preview()
    # the levels' sizes: the level's, or a few pixels less where a side would be a power of two
    # (llvmpipe's shader variants are shared by textures alike in that: no level compiles its own)
    for lv in (2, 3):
        w, h = s.previews.engines[lv].scene.width, s.previews.engines[lv].scene.height
        assert PREVIEW_LEVELS[lv].work - 8 < max(w, h) <= PREVIEW_LEVELS[lv].work and w & (w - 1) and h & (h - 1)
    s.release()


def test_the_coarse_frame_after_a_drag_is_a_live_preview_engine_until_the_engines_are_made_again(ctx):
    """The window shows render_coarse's engine while the sharp frame is drawn; a quality preset makes
    the engines again: the window then stops showing it (ViewerApp._render checks it is still one of
    the session's preview engines; a released one crashed the window)."""
    scene = load_scene(sample_scene_dir())
    lights = load_lights(MAPS / "immenstadter_horn_256.lights.json")
    s = Session(ctx, scene, lights, load_envmap(MAPS / "immenstadter_horn_256.hdr").pixels)
    s.render(preview=True)
    key = s.state_key()
    coarse = s.render_coarse()
    assert coarse.complete and coarse in s.previews.engines.values()
    assert coarse.looks.asked.shadows == "soft" and coarse.looks.asked.skin == s.look.skin  # full quality, coarser
    s.update(exposure=1.0)
    assert s.state_key() != key  # a change while the sharp frame is drawn: the window settles again
    s.set_options(EngineOptions(shadow_resolution=256))
    assert coarse not in s.previews.engines.values()
    s.release()


def test_a_new_person_comes_in_over_budgeted_calls_the_old_one_shown_meanwhile(ctx):
    """The window opening a photo: the new person's engine is made in one frame, given the map in
    another (not in a frame whose time went on making it), drawn over budgeted frames; the old
    person stays on screen until the new frame is complete, which is a fresh session's frame."""
    from viewer.scene.resampling import resample_scene

    lights = load_lights(MAPS / "immenstadter_horn_256.lights.json")
    env = load_envmap(MAPS / "immenstadter_horn_256.hdr").pixels
    old = load_scene(sample_scene_dir())
    new = resample_scene(old, 200)
    s = Session(ctx, old, lights, env)
    s.update(yaw=60.0)
    before = s.render().output.read_display().copy()
    s.set_scene(new)
    assert s.ground_shown == s.look.ground_shown(s.final.feet, "environment")  # the map on its way counts
    shown = s.render(budget=0.06)  # the frame that made the engine: nothing more in it
    assert shown is not s.final and s._map_pending
    np.testing.assert_array_equal(shown.output.read_display(), before)
    shown = s.render(budget=0.0)  # the next frame: the map, whatever its budget, nothing else
    assert not s._map_pending and shown is not s.final and s.final.kit.counters["shadow_map"] == 0
    calls = 0
    while True:
        shown = s.render(budget=0.0)
        calls += 1
        if shown is s.final:
            break
        np.testing.assert_array_equal(shown.output.read_display(), before)
        assert calls < 200
    fresh = Session(ctx, new, lights, env)
    fresh.update(yaw=60.0)
    np.testing.assert_array_equal(shown.output.read_display(), fresh.render().output.read_display())
    fresh.release()
    s.release()
