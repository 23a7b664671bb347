"""The ground shadow (Look.ground, viewer/gl/ground_pass.py, viewer/scene/ground.py): the person's shadow
on the ground at the feet darkens the background where the person blocks the light, and only
there; it runs only while shown and only when the lights change; the plane goes through the feet,
each foot darkens the ground it stands on, and the shadow is on by default when the feet are in
the frame and the map is behind the person."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import render_by_units

from viewer.gl import Engine, EngineOptions
from viewer.resources import sample_scene_dir
from viewer.scene.area_lights import AreaLights, rotation_matrix
from viewer.scene.bundle import FrameLayer, Scene, load_scene
from viewer.scene.camera import Camera
from viewer.scene.ground import MAX_TILT, contacts, ground_plane
from viewer.scene.look import Look
from viewer.scene.resampling import resample_scene

SUN = np.array([0.5, 0.6, 0.45]) / np.linalg.norm([0.5, 0.6, 0.45])  # above, right, in front


def relook(eng, **changes):
    """The engine's look with ``changes`` (the display fields, the terms shown)."""
    eng.set_look(eng.look.replace(**changes))


@pytest.fixture(scope="module")
def person():
    return resample_scene(load_scene(sample_scene_dir()), 128)


def sun_and_sky(sigma: float = 1.0) -> AreaLights:
    return AreaLights(np.array([SUN, [0.0, 1.0, 0.0]]), np.array([sigma, 12.0]), np.array([[6.0, 6.0, 6.0], [0.4, 0.45, 0.6]]))


def engine(ctx, scene, lights, **look):
    eng = Engine(ctx, scene, EngineOptions(shadow_resolution=256))
    eng.set_lights(lights)
    eng.set_look(Look(background="color", background_color=(0.5, 0.5, 0.5), **look))
    eng.render()
    return eng


def test_the_shadow_falls_away_from_the_sun_on_the_background_only(ctx, person):
    off = engine(ctx, person, sun_and_sky())
    before = off.output.read_display().astype(int)
    assert off.kit.counters["ground_shadow"] == 0  # left out while not shown
    off.release()
    eng = engine(ctx, person, sun_and_sky(), ground=True)
    after = eng.output.read_display().astype(int)
    occ = eng.output.read_ground_shadow()
    assert occ.shape == (64, 64, 3) and np.all(np.isfinite(occ)) and occ.min() >= 0.0 and occ.max() <= 1.0 + 1e-6
    assert occ.max() > 0.5  # the sun is most of the ground's light
    mask = person.mask
    assert np.array_equal(after[mask], before[mask])  # the person is not the ground
    darker = (before - after).max(axis=-1) > 8
    assert darker[~mask].sum() > 50
    rows, cols = np.nonzero(darker & ~mask)
    feet_row = np.nonzero(mask.any(axis=1))[0].max()
    feet_col = np.nonzero(mask[feet_row])[0].mean()
    assert rows.min() > person.height // 2  # on the ground, below the horizon
    assert cols.mean() < feet_col  # the sun is on the right: the shadow goes left
    assert np.all(after[: person.height // 2] == before[: person.height // 2])  # nothing above the horizon changes
    eng.release()


def test_lights_below_the_ground_cast_nothing_on_it(ctx, person):
    under = AreaLights(np.array([[0.3, -0.5, 0.8]]) / np.linalg.norm([0.3, -0.5, 0.8]), np.array([1.0]), np.array([[3.0, 3.0, 3.0]]))
    eng = engine(ctx, person, under, ground=True)
    assert np.all(eng.output.read_ground_shadow() == 0.0)
    eng.release()


def test_a_larger_light_softens_the_shadow_on_the_ground(ctx, person):
    def partial(sigma):
        eng = engine(ctx, person, AreaLights(SUN[None], np.array([sigma]), np.array([[5.0, 5.0, 5.0]])), ground=True)
        occ = eng.output.read_ground_shadow()[..., 0]
        eng.release()
        return ((occ > 0.05) & (occ < 0.95)).sum() / max((occ > 0.05).sum(), 1)

    assert partial(12.0) > partial(0.0) + 0.1


def test_the_ground_is_redone_only_when_the_lights_change(ctx, person):
    eng = engine(ctx, person, sun_and_sky(), ground=True)

    def runs(action):
        start = eng.kit.counters["ground_shadow"]
        action()
        eng.render()
        return eng.kit.counters["ground_shadow"] - start

    assert runs(lambda: relook(eng, exposure=1.0)) == 0
    assert runs(lambda: eng.set_lights(sun_and_sky().scaled(2.0))) == 1
    assert runs(lambda: eng.set_lights(sun_and_sky(4.0))) == 1
    assert runs(lambda: eng.set_look(eng.look.replace(ground=False))) == 0
    assert runs(lambda: eng.set_lights(sun_and_sky().rotated(30.0))) == 0  # stale, but not shown
    assert runs(lambda: eng.set_look(eng.look.replace(ground=True))) == 1
    eng.set_look(eng.look.replace(shadows="none"))
    eng.render()
    assert np.all(eng.output.read_ground_shadow() == 0.0)  # no shadows shown: none on the ground either
    eng.release()


def test_a_photo_frame_and_its_exr_carry_the_ground_shadow(ctx, person):
    up = lambda a: np.repeat(np.repeat(a, 2, axis=0), 2, axis=1)  # noqa: E731
    photo = np.full(up(person.albedo).shape, 0.4, np.float32)
    sc = replace(person, frame=FrameLayer(albedo=up(person.albedo), alpha=up(person.mask.astype(np.float32)), photo=photo))
    out = {}
    for ground in (False, True):
        eng = engine(ctx, sc, sun_and_sky(), ground=ground, compare=0.0)
        eng.set_look(eng.look.replace(background="photo"))
        eng.render()
        out[ground] = (eng.output.read_display().astype(int), eng.output.read_output_hdr()[..., :3])
        eng.release()
    (d0, h0), (d1, h1) = out[False], out[True]
    matte = up(person.mask)
    assert np.array_equal(d1[matte], d0[matte])
    assert ((d0 - d1).max(axis=-1) > 8)[~matte].sum() > 200
    assert np.all(h1 <= h0 + 1e-6) and (h0 - h1).max() > 0.1  # the EXR: the photo's background darkened


def test_the_ground_shadow_against_mitsuba(tmp_path):
    """relight bench ground at a small size: the ray-traced ground under a low sun and under the
    bundled map; contact-hardening soft shadows are closer to it than hard ones, within bounds."""
    from viewer.lab.bench.ground import run_ground_benchmark

    rows = run_ground_benchmark(str(tmp_path / "ground.json"), size=128, spp=32, repeats=1)["rows"]
    err = {(r["lighting"], r["method"]): r["mae"] for r in rows}
    for lighting, bound in (("low sun", 0.2), ("mountain map", 0.06)):
        assert err[(lighting, "pcss")] < err[(lighting, "hard")]
        assert err[(lighting, "pcss")] < bound
    assert all(r["shadow_pixels_truth"] > 50 and r["shadow_pixels_engine"] > 50 for r in rows)
    assert (tmp_path / "ground.json").is_file()
    contact = {(r["lighting"], r["method"]): r for r in rows}
    for lighting, bound in (("low sun", 0.06), ("mountain map", 0.12), ("studio map", 0.08)):
        row = contact[(lighting, "pcss")]
        assert row["contact_mae"] < bound, (lighting, row["contact_mae"])


def test_the_feet_are_found_where_the_person_ends_above_the_frame(person):
    feet = contacts(person.mask)
    assert 1 <= len(feet) <= 2
    bottom = np.nonzero(person.mask.any(axis=1))[0].max()
    assert all(y == bottom or y > bottom - 0.05 * person.height for _, y in feet)
    cut = person.mask.copy()
    cut[bottom - 10:] = person.mask[bottom - 10]  # the person cut off by the frame's bottom edge
    cut[-1] = cut[bottom - 10]
    assert contacts(cut) == [] and contacts(np.zeros_like(cut)) == []


def _two_feet(front_depth: float, back_depth: float):
    """A synthetic person: a body over two feet blobs, the right one lower in the image and nearer."""
    h, w = 120, 80
    mask = np.zeros((h, w), bool)
    mask[10:90, 25:55] = True
    mask[90:110, 28:38] = True  # left foot, bottom row 109
    mask[90:114, 44:54] = True  # right foot, bottom row 113
    depth = np.full((h, w), 4.0, np.float32)
    depth[:, :40] = back_depth
    depth[:, 40:] = front_depth
    normal = np.zeros((h, w, 3), np.float32)
    normal[mask, 2] = 1.0
    return Scene(albedo=np.where(mask[..., None], np.float32(0.5), np.zeros((h, w, 3), np.float32)), specular=np.zeros((h, w), np.float32),
                 roughness=np.full((h, w), 0.5, np.float32), normal=normal, depth=depth, mask=mask,
                 camera=Camera(w, h)).validate()


def test_the_plane_goes_through_both_feet():
    scene = _two_feet(3.9, 4.05)
    plane = ground_plane(scene)
    assert plane.feet and len(plane.contacts) == 2
    heights = plane.contacts @ plane.normal - plane.offset
    assert np.abs(heights).max() < 1e-4  # both soles on the plane
    tilt = np.degrees(np.arccos(plane.normal[1]))
    assert 0.0 < tilt <= MAX_TILT and plane.below_camera
    steep = ground_plane(_two_feet(2.0, 6.0))  # depths that would tilt it past MAX_TILT: level at the lower foot
    assert np.allclose(steep.normal, [0.0, 1.0, 0.0]) and np.isclose(steep.offset, steep.contacts[:, 1].min())


def test_a_foot_whose_lowest_row_is_in_pieces_still_stands_on_the_plane():
    """A foot blob whose lowest row is two pixels 10 px apart (a heel and a toe; a street clip's frame
    matted so stopped its inference with a traceback): its contact is one of its own pixels, and the
    plane goes through it."""
    scene = _two_feet(3.9, 4.05)
    mask = scene.mask.copy()
    mask[110:114, 44:54] = False  # the right foot's toe and heel reach lower, apart
    mask[110:114, 44] = mask[110:114, 53] = True
    plane = ground_plane(replace(scene, mask=mask).validate())
    assert plane.feet and len(plane.contacts) == 2
    for x, y in contacts(mask):
        assert mask[y, x]


def test_each_foot_darkens_the_ground_it_stands_on(ctx, person):
    """Under a sky of 16 lights, the feet's contact points darken the ground beside them beyond
    what the shadow maps alone do (the occlusion at contact their bias leaves out)."""
    from viewer.lighting.lightfit.fit import fibonacci_sphere

    dirs = fibonacci_sphere(32)
    dirs = dirs[dirs[:, 1] > 0.1][:16]
    sky = AreaLights(dirs, np.full(len(dirs), 6.0), np.full((len(dirs), 3), 0.2))
    occlusion = {}
    for with_contact in (True, False):
        eng = Engine(ctx, person, EngineOptions(shadow_resolution=256))
        if not with_contact:
            eng.ground_pass.plane = replace(eng.ground_pass.plane, contact_points=np.zeros((0, 4), np.float32))
        eng.set_lights(sky)
        eng.set_look(Look(background="color", ground=True))
        eng.render()
        occlusion[with_contact] = eng.output.read_ground_shadow().mean(axis=-1)
        eng.release()
    extra = occlusion[True] - occlusion[False]
    x, y = contacts(person.mask)[0]
    i, j = np.unravel_index(np.argmax(extra), extra.shape)
    assert extra.max() > 0.05 and abs(i - y // 2) <= 4 and abs(j - x // 2) <= 8  # at the foot
    assert extra.min() > -1e-6  # it only adds shadow
    far = np.ones(extra.shape, bool)
    far[max(y // 2 - 12, 0):, max(x // 2 - 20, 0):x // 2 + 20] = False
    assert np.abs(extra[far]).max() < 0.01  # farther, what the feet hide falls off with the distance squared


def test_the_ground_shows_by_default_when_the_feet_are_in_the_frame(ctx, person):
    eng = Engine(ctx, person, EngineOptions(shadow_resolution=256))
    eng.set_lights(sun_and_sky())
    assert eng.feet
    eng.set_look(Look(background="environment"))
    assert not eng.ground_shown and eng.look.background != "environment"  # no map yet: the background falls back
    eng.set_environment(np.ones((8, 16, 3), np.float32))
    for background, ground, shown in (("environment", "auto", True), ("color", "auto", False),
                                      ("environment", False, False), ("color", True, True)):
        eng.set_look(Look(background=background, ground=ground))
        assert eng.ground_shown == shown, (background, ground)
    eng.release()
    cut = replace(person, mask=person.mask.copy())
    bottom = np.nonzero(cut.mask.any(axis=1))[0].max()
    cut.mask[bottom:] = cut.mask[bottom]  # the feet cut off by the frame's bottom edge
    eng = Engine(ctx, cut, EngineOptions(shadow_resolution=256))
    eng.set_look(Look(background="environment"))
    assert not eng.feet and not eng.ground_shown
    eng.release()
    with pytest.raises(Exception, match="ground must be true or false"):
        Look(ground="sometimes")


def framed_person(person):
    up = lambda a: np.repeat(np.repeat(a, 2, axis=0), 2, axis=1)  # noqa: E731
    return replace(person, frame=FrameLayer(albedo=up(person.albedo), alpha=up(person.mask.astype(np.float32)),
                                            photo=np.full(up(person.albedo).shape, 0.4, np.float32)))


def ten_lights() -> AreaLights:
    rng = np.random.default_rng(3)
    d = rng.normal(size=(10, 3))
    d[:, 1] = np.abs(d[:, 1]) + 0.3  # from above: shadows on the ground
    return AreaLights(d / np.linalg.norm(d, axis=1, keepdims=True), rng.uniform(0, 6, 10), rng.uniform(0.2, 1.0, (10, 3)))


def budgeted_until(eng, done):
    """Budgeted calls (one unit each) until ``done(eng)``."""
    for _ in range(300):
        if done(eng):
            return
        eng.render(budget=0.0)
    raise AssertionError("a budgeted render did not get there")


def test_work_left_part_way_starts_again_when_anything_changed_meanwhile(ctx, person):
    """The ground's groups left part-way, the ground hidden, new lights rendered in full, the ground
    shown again; the frame's bands left part-way, new lights, a readback: what a budgeted render
    ends with is the full render's, not half of each lighting."""
    sc, lights = framed_person(person), ten_lights()
    eng = engine(ctx, sc, lights, ground=True)
    eng.set_lights(lights.rotated(60.0))
    budgeted_until(eng, lambda e: (e.ground_pass._next or (0, 0)) > (0, 0))  # (group, band) left part-way
    relook(eng, ground=False)
    eng.set_lights(lights.rotated(120.0))
    eng.render()
    relook(eng, ground=True)
    budgeted_until(eng, lambda e: e.complete)
    eng.set_lights(lights.rotated(200.0))
    budgeted_until(eng, lambda e: e.picture._bands is not None and e.picture._bands["frame"] >= 2)
    eng.set_lights(lights.rotated(240.0))
    eng.render(display=False)
    eng.output.read_output_hdr()  # builds the frame's inputs for the new lights
    budgeted_until(eng, lambda e: e.complete)
    fresh = engine(ctx, sc, lights.rotated(240.0), ground=True)
    np.testing.assert_array_equal(eng.output.read_display(), fresh.output.read_display())
    eng.set_lights(lights.rotated(120.0))
    eng.render()
    fresh.set_lights(lights.rotated(120.0))
    fresh.render()
    np.testing.assert_array_equal(eng.output.read_ground_shadow(), fresh.output.read_ground_shadow())
    fresh.release()
    eng.release()


def test_a_budgeted_photo_frame_comes_in_by_units_and_never_shows_half_a_frame(ctx, person):
    """A window bringing in a new map over a photo (Engine.render with a budget): the ground's shadow
    a band of a group of lights a call, the frame's background and composite a band of rows a call; until the
    new frame is whole the display keeps the last one, and the frame it ends with is the full
    render's, also when the look changes half-way (the bands start again)."""
    sc, lights = framed_person(person), ten_lights()
    for background in ("photo", "color"):
        eng = engine(ctx, sc, lights, ground=True)
        relook(eng, background=background)
        eng.render()
        before = eng.output.read_display().copy()
        eng.set_lights(lights.rotated(60.0))

        changed = []

        def half_way(calls, eng=eng, changed=changed):
            bands = eng.picture._bands
            if not changed and bands is not None and bands["frame"] == 2:
                relook(eng, exposure=0.7)  # the look changes half-way (in the frame's bands)
                changed.append(calls)

        calls = render_by_units(eng, before, half_way)
        assert changed
        # shadow maps, light passes and the ground by bands of each group, the composite, the frame by
        # bands (half of them twice)
        assert calls >= 10 + 3 * 4 + 1 + 3 * 4 + 4 + 2
        fresh = engine(ctx, sc, lights.rotated(60.0), ground=True)
        relook(fresh, background=background, exposure=0.7)
        fresh.render()
        np.testing.assert_array_equal(eng.output.read_display(), fresh.output.read_display())
        np.testing.assert_array_equal(eng.output.read_ground_shadow(), fresh.output.read_ground_shadow())
        fresh.release()
        eng.release()


class Clockless:  # a GL context whose work is done at once (WorkBudget's tests)
    def finish(self):
        pass


def test_a_budget_does_not_start_a_unit_it_has_no_time_left_for():
    from viewer.gl.work_budget import WorkBudget

    costs = {"long": 10.0}  # seconds it took last time
    assert not WorkBudget(Clockless(), 1.0, dict(costs)).spent("long")  # the first unit always runs
    work = WorkBudget(Clockless(), 1.0, costs)
    assert not work.spent("short")
    assert work.spent("long")  # it would pass the budget: not started
    assert not work.spent("short") and costs["short"] < 0.5  # what ran is timed for next time
    assert WorkBudget(Clockless(), None, costs).spent("long") is False  # no budget: never spent


def test_a_unit_never_timed_counts_as_long_as_the_longest_of_the_call():
    """A new engine's first budgeted frame: its units have no time yet; one is not started when the
    longest unit of the call so far would not fit in what is left."""
    import time

    from viewer.gl.work_budget import WorkBudget

    work = WorkBudget(Clockless(), 0.05, {})
    assert not work.spent("slow")
    time.sleep(0.03)  # the unit took 30 ms: 20 ms are left
    assert work.spent("new")  # never timed: expected to take 30 ms too, so not started
    quick = WorkBudget(Clockless(), 0.05, {})
    assert not quick.spent("fast") and not quick.spent("new")  # the call's units so far were short


def test_a_map_with_no_ground_gets_a_floor_behind_the_feet(ctx, person, tmp_path):
    """A sky-only map (its lower half black) leaves the feet over darkness: a floor of 18 % albedo lit
    by the map's sky is laid under its horizon, behind the person only (the map's file, and every map
    with a ground, unchanged: the bundled ones, and the shared ones where they are), and the command says so."""
    from conftest import SHARED_DATA
    from test_cli import run_cli

    from viewer.files.imageio import write_exr
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.floor import FLOOR_ALBEDO, ground_share, laid_floor
    from viewer.resources import asset_dir

    sky = np.zeros((64, 128, 3), np.float32)
    sky[:32] = [2.0, 1.8, 1.6]  # a uniform sky: a white floor under it reflects its radiance
    assert ground_share(sky) == 0.0
    floor = laid_floor(sky)
    np.testing.assert_allclose(floor[40:], np.broadcast_to(FLOOR_ALBEDO * sky[0, 0], floor[40:].shape), rtol=0.01)
    assert (floor[:32] == sky[:32]).all()
    maps = sorted(asset_dir().glob("envmaps/*.hdr")) + sorted((SHARED_DATA / "hdri").glob("*.hdr"))
    for path in maps:
        pixels = load_envmap(path).pixels
        assert laid_floor(pixels) is pixels, (path, ground_share(pixels))

    eng = Engine(ctx, person, EngineOptions(shadow_resolution=256))
    eng.set_lights(sun_and_sky())
    eng.set_environment(sky)
    eng.set_look(Look(background="environment", exposure=0.0))
    eng.render()
    shown = eng.output.read_display().astype(float)
    rows = np.nonzero(person.mask.any(axis=1))[0]
    below = shown[rows.max() + 2:]  # the backdrop under the feet
    assert below.size and below.mean() > 40, below.mean()  # a grey floor, not black
    eng.release()

    write_exr(tmp_path / "sky_only.exr", sky)
    res = run_cli("render", str(sample_scene_dir()), "--env", str(tmp_path / "sky_only.exr"), "-o", str(tmp_path / "out.png"))
    assert res.returncode == 0, res.stderr
    assert "the map shows no ground" in res.stdout and "grey floor" in res.stdout
    assert (load_envmap(tmp_path / "sky_only.exr").pixels[40:] == 0).all()  # the file as it was


def test_the_maps_ground_is_seen_from_the_cameras_height(ctx, person):
    """A camera 4 m above the ground (Look.camera_height, a clip's, viewer/output/clip_frames.py) sees the
    map's ground as the map's own camera (MAP_CAMERA_HEIGHT_M up) sees the same points of the ground plane:
    below the horizon each ray's height is scaled by their ratio, above it nothing changes; the display
    shader draws what EnvMap.seen_through computes (a map whose rows ramp from the zenith to the nadir)."""
    from viewer.files.imageio import srgb_to_linear
    from viewer.lighting.envmap import EnvMap
    from viewer.scene.look import MAP_CAMERA_HEIGHT_M

    ramp = np.repeat(((np.arange(64) + 0.5) / 64.0)[:, None, None], 128, axis=1) * np.ones(3)
    env = EnvMap(ramp.astype(np.float32))
    eng = Engine(ctx, person, EngineOptions(shadow_resolution=256))
    eng.set_lights(sun_and_sky())
    eng.set_environment(env.pixels)
    away = ~np.asarray(person.mask)  # the backdrop, where no person covers it
    shown = {}
    for height in (0.0, 4.0):
        look = Look(background="environment", exposure=0.0, tonemap="clamp", ground=False, tilt=8.0, camera_height=height)
        eng.set_look(look)
        eng.render()
        shown[height] = srgb_to_linear(eng.output.read_display().astype(np.float64) / 255.0)
        expected = env.seen_through(person.camera, 0.0, 8.0, look.ground_squash)
        assert np.abs(shown[height] - expected)[away].max() < 0.03, height
    assert Look(camera_height=4.0).ground_squash == pytest.approx(MAP_CAMERA_HEIGHT_M / 4.0)
    from viewer.errors import InputError

    for bad in (1e-20, -1.0, float("nan")):  # a ground squashed past a float, below the camera, no number
        with pytest.raises(InputError, match="camera height"):
            Look(camera_height=bad)
    rows = person.camera.view_directions() @ rotation_matrix(0.0, 8.0)
    sky, ground = (rows[..., 1] > 0.02) & away, (rows[..., 1] < -0.2) & away
    assert sky.any() and ground.any()
    assert np.abs(shown[4.0] - shown[0.0])[sky].max() < 0.01  # the sky as it was
    # seen from higher up, the ground near the feet is the map's ground farther off: nearer the horizon, darker
    assert (shown[0.0] - shown[4.0])[ground].mean() > 0.05
    eng.release()
