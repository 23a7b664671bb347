"""The viewer as a person uses it: a real window on Xvfb, driven with xdotool (mouse drags, clicks,
keys), checked through the files it saves (S: PNG + EXR + JSON; R: MP4) against headless renders."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from viewer.app.preview import PREVIEW_LEVELS
from viewer.cli.commands import DEMO_LIGHTS
from viewer.files.imageio import read_exr, read_png
from viewer.gl import Engine, EngineOptions
from viewer.lab.bench.metrics import detail_kept
from viewer.lab.bench.viewer import x_display
from viewer.output.video import partial_path, read_video
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.area_lights import facing_yaw, load_lights
from viewer.scene.bundle import load_scene
from viewer.scene.look import Look
from viewer.scene.resampling import resample_scene

# the viewer opens with the brightest light turned toward the camera (no --yaw given)
FIRST_YAW = facing_yaw(load_lights(asset_dir() / DEMO_LIGHTS))

SIZE = 256
RELIGHT = [sys.executable, "-m", "viewer.cli.main"]


@pytest.fixture(scope="module")
def display():
    """A private X server (Xvfb) for this module's windows."""
    with x_display(private=True) as name:
        yield name


class Viewer:
    """``relight view`` in a subprocess, with its state file to wait on."""

    def __init__(self, display: str, tmp: Path, *args: str):
        self.display = display
        self.state_path = tmp / "state.json"
        self.out = tmp / "captures"
        self.env = {**os.environ, "DISPLAY": display}
        self.proc = subprocess.Popen([*RELIGHT, "view", "--size", str(SIZE), "--state-file", str(self.state_path),
                                      "--out-dir", str(self.out), *args], env=self.env, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        self.wait_for(lambda s: s["frame_count"] >= 2 and not s["fitting"], 120)

    def state(self) -> dict | None:
        try:
            return json.loads(self.state_path.read_text())
        except (OSError, json.JSONDecodeError):
            return None

    def wait_for(self, predicate, timeout: float = 60) -> dict:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if self.proc.poll() is not None:
                raise AssertionError(f"viewer exited ({self.proc.returncode}): {self.proc.stderr.read()[-2000:]}")
            s = self.state()
            if s is not None and predicate(s):
                return s
            time.sleep(0.1)
        raise AssertionError(f"timed out; last state: { {k: v for k, v in (self.state() or {}).items() if k != 'frames'} }")

    def xdotool(self, *args):
        subprocess.run(["xdotool", *map(str, args)], env=self.env, check=True)

    def click(self, name, fx=0.5, fy=0.5, until=None):
        """Click a widget of the panel (its place in the state file); with ``until``, wait for the
        state it should bring, clicking again when a click went unseen (once in a full run the 29x13
        "aim" button's click changed nothing for 30 s; it did not happen again in 5 runs of this
        file; the cause is not found)."""
        for attempt in range(3):
            x0, y0, x1, y1 = self.state()["widgets"][name]
            self.xdotool("mousemove", int(x0 + fx * (x1 - x0)), int(y0 + fy * (y1 - y0)))
            time.sleep(0.2)
            self.xdotool("click", 1)
            if until is None:
                return None
            try:
                return self.wait_for(until, 10)
            except AssertionError:
                if attempt == 2:
                    raise

    def drag(self, x, y, dx, dy, steps=10):
        self.xdotool("mousemove", x, y)
        time.sleep(0.2)
        self.xdotool("mousedown", 1)
        time.sleep(0.2)
        for _ in range(steps):
            self.xdotool("mousemove_relative", "--", dx // steps, dy // steps)
            time.sleep(0.05)
        time.sleep(0.2)
        self.xdotool("mouseup", 1)

    def save(self) -> Path:
        count = len(self.state()["captures"])
        self.xdotool("key", "s")
        return Path(self.wait_for(lambda s: len(s["captures"]) > count)["captures"][-1])

    def quit(self) -> int:
        self.xdotool("key", "q")
        return self.proc.wait(30)

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture
def viewer_factory(display, tmp_path):
    started = []

    def start(*args):
        v = Viewer(display, tmp_path, *args)
        started.append(v)
        return v

    yield start
    for v in started:
        v.close()


@pytest.fixture(scope="module")
def headless(ctx):
    scene = resample_scene(load_scene(sample_scene_dir()), SIZE)
    lights = load_lights(asset_dir() / DEMO_LIGHTS)
    from viewer.lighting.envmap import load_envmap

    env = load_envmap(asset_dir() / "envmaps/immenstadter_horn_256.hdr").pixels
    engine = Engine(ctx, scene, EngineOptions())
    engine.set_environment(env)
    yield scene, lights, engine
    engine.release()


def render_hdr(headless, yaw, lights=None):
    scene, base, engine = headless
    engine.set_lights(lights or base)
    engine.set_look(Look(yaw=yaw))
    engine.render()
    return engine.output.read_output_hdr()[..., :3]  # what a saved frame's EXR holds: the display's HDR, background included


def rel_l1(a, b):
    return float(np.abs(a - b).sum() / max(np.abs(b).sum(), 1e-12))


def test_drag_turns_the_lighting_and_the_map(viewer_factory, headless):
    v = viewer_factory()
    tops = lambda s: {name: rect[1] for name, rect in s["widgets"].items()}  # noqa: E731
    before = tops(v.state())
    first = v.save()
    s = v.state()
    moved = {k: v for k, v in tops(s).items() if k in before}
    assert s["message"].startswith("saved") and moved == before  # a message moves no widget down
    # it says the folder (--out-dir, whole), and the panel copies it (issue 45)
    assert s["message"].endswith(f" in {s['out_dir']}") and Path(s["out_dir"]) == first.parent.resolve()
    assert "copy folder" in s["widgets"]
    x, y, w, h = s["image_rect"]
    v.drag(int(x + w * 0.4), int(y + h * 0.5), 60, 0)
    # 0.5 degrees per pixel; dragging right turns the map (and its lights) to the right
    s = v.wait_for(lambda s: abs(s["look"]["yaw"] - (FIRST_YAW - 30.0)) < 1e-6, 30)
    second = v.save()
    a, b = read_exr(first.with_suffix(".exr")), read_exr(second.with_suffix(".exr"))
    assert rel_l1(a, render_hdr(headless, FIRST_YAW)) < 1e-3
    assert rel_l1(b, render_hdr(headless, FIRST_YAW - 30.0)) < 1e-3
    assert rel_l1(b, a) > 0.05  # the picture changed: highlights and shadows moved with the lights
    # the saved lights are the rotated ones the frame was rendered with
    saved = json.loads(second.with_suffix(".json").read_text())
    assert saved["look"]["yaw"] == pytest.approx(FIRST_YAW - 30.0)
    lights = headless[1].rotated(FIRST_YAW - 30.0)
    np.testing.assert_allclose([l["direction"] for l in saved["lights"]["lights"]], lights.direction, atol=1e-5)
    # the panel's frame-time record saw preview frames during the drag, then the full-quality frame at
    # the preview's level, then the sharp one (drawn behind it over budgeted frames, issue 45)
    s = v.state()
    kinds = [k for _, k in s["frames"]]
    after = kinds[len(kinds) - kinds[::-1].index("drag"):]
    assert "settle" in after and "update" in after[after.index("settle"):]
    assert 0 < s["settle"]["full_quality_ms"] <= s["settle"]["sharp_ms"]
    assert 0 <= s["preview_level"] < len(PREVIEW_LEVELS)
    # the window can be resized (the image is fitted into the new area), and closing it exits cleanly
    wid = subprocess.run(["xdotool", "search", "--name", "^relight$"], env=v.env, capture_output=True, text=True,
                         check=True).stdout.split()[0]
    v.xdotool("windowsize", wid, 700, 600)
    s = v.wait_for(lambda s: s["image_rect"][2] == pytest.approx(400.0), 30)  # 700 - the panel, 300 pixels there
    assert s["image_rect"][3] == pytest.approx(400.0)
    # at 900 x 700 the panel narrows to a third of the window and every widget stays inside it, its
    # label too (issue 45: "before | afte" was cut at 973 pixels), at three sizes
    for size in ((900, 700), (973, 760), (1280, 1000)):
        v.xdotool("windowsize", wid, *size)
        s = v.wait_for(lambda s, size=size: s["window_size"] == list(size), 30)
        time.sleep(0.5)
        s = v.state()
        left = s["image_rect"][0] + s["image_rect"][2]
        for name, (x0, _, x1, _) in s["widgets"].items():
            assert left <= x0 and x1 <= s["panel_right"] + 0.5, (size, name, x0, x1, s["panel_right"])
    assert s["image_rect"][2] >= 594.0
    assert v.state()["id_conflicts"] == []  # no two widgets share an imgui ID (issue 45)
    assert v.quit() == 0


def test_a_photo_is_inferred_and_shown_with_refined_shadows(viewer_factory, tmp_path, monkeypatch):
    """relight view PHOTO: the person found automatically, inference once (cached), then the
    viewer; the refined shadow mode fills in when the lighting is still; a saved frame has the
    photo's own size, with the person where the photo has them."""
    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache" / "lights"))
    photo = asset_dir() / "photos" / "underpass.jpg"
    v = viewer_factory(str(photo), "--visibility", "refined")
    s = v.wait_for(lambda s: s["refined"], 120)
    assert s["look"]["shadows"] == "refined" and not s["refine_error"]
    assert len(list((tmp_path / "cache" / "bundles").glob("underpass-*/scene.json"))) == 1
    shot = read_png(v.save())
    assert shot.shape[:2] == (1024, 681)
    hand = read_png(photo.with_suffix(".mask.png")) > 0.5
    hand = hand if hand.ndim == 2 else hand[..., 0]
    assert 0.7 < detail_kept(shot, read_png(photo), hand) < 1.3  # the photo's own detail, in its own place
    # before / after: B shows the original photo left of the middle, B again the relit frame alone
    v.xdotool("key", "b")
    v.wait_for(lambda s: s["look"]["compare"] == 0.5)
    split = read_png(v.save())
    original = read_png(photo)
    assert np.abs(split[:, :330] - original[:, :330]).mean() < 2.0 / 255  # the photo as it was
    assert np.abs(split[:, 345:] - shot[:, 345:]).mean() < 1e-6  # the relit frame beside it
    v.xdotool("key", "b")
    v.wait_for(lambda s: s["look"]["compare"] == 0.0)
    # a new map keeps the exposure chosen when the photo opened, so a dark map looks dark; "level"
    # exposes for the photo's brightness under it (issue 45)
    from viewer.files.imageio import write_exr
    from viewer.lighting.envmap import load_envmap

    dark = write_exr(tmp_path / "dark.exr", load_envmap(asset_dir() / "envmaps" / "venice_sunset_256.hdr").pixels / 32.0)
    opened = v.state()["look"]["exposure"]

    v.click("open a file")
    v.wait_for(lambda s: "browser path" in s["widgets"], 30)
    v.click("browser path")
    v.xdotool("type", str(dark))
    v.click("browser open")
    s = v.wait_for(lambda s: s["map"] == str(dark) and not s["fitting"], 120)
    assert s["look"]["exposure"] == pytest.approx(opened)
    s = v.click("level exposure", until=lambda s: s["look"]["exposure"] != pytest.approx(opened))  # (again if unseen)
    assert s["look"]["exposure"] > opened + 3.0  # 32 times darker: about 5 stops more
    assert v.state()["id_conflicts"] == []  # no two widgets share an imgui ID (issue 45)
    assert v.quit() == 0


def test_the_photos_own_background_is_shown_as_it_is_whatever_the_exposure(viewer_factory, tmp_path, monkeypatch):
    """relight view PHOTO --background photo: behind the person the photo as it was, at any exposure
    (the panel's "behind" offers it too)."""
    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache" / "lights"))
    photo = asset_dir() / "photos" / "underpass.jpg"
    v = viewer_factory(str(photo), "--background", "photo", "--exposure", "2")
    s = v.wait_for(lambda s: s["look"]["background"] == "photo" and "behind" in s["widgets"], 60)
    assert s["look"]["exposure"] == 2.0
    shot, original = read_png(v.save()), read_png(photo)
    mask = read_png(photo.with_suffix(".mask.png"))
    away = (mask if mask.ndim == 2 else mask[..., 0]) == 0
    assert np.abs(shot[away] - original[away]).mean() < 1.0 / 255  # the photo as it was, not two stops brighter
    assert v.quit() == 0


def test_sigma_slider_softens_that_lights_shadow(viewer_factory, headless):
    scene, base, engine = headless
    v = viewer_factory()
    k = int(np.argmax(base.intensity.sum(axis=1)))  # the brightest light: its shadow shows most
    s = v.state()
    x0, y0, x1, y1 = s["widgets"][f"sigma {k}"]
    old = s["sigma"][k]
    v.xdotool("mousemove", int(x0 + 0.9 * (x1 - x0)), int((y0 + y1) / 2))
    time.sleep(0.2)
    v.xdotool("click", 1)
    s = v.wait_for(lambda s: s["sigma"][k] > old + 10, 30)
    new = s["sigma"][k]
    shot = v.save()
    shown = read_exr(shot.with_suffix(".exr"))
    softer = base.with_sigma(k, new)
    assert rel_l1(shown, render_hdr(headless, FIRST_YAW, softer)) < 1e-3
    assert rel_l1(shown, render_hdr(headless, FIRST_YAW)) > 1e-3

    def penumbra(lights):
        """Pixels facing the light (away from its terminator) that are partly shadowed."""
        render_hdr(headless, FIRST_YAW, lights)
        out = engine.output.read_light(k)
        facing = out["diffuse"] > 0.05
        vis = out["visibility_soft"][facing]
        return int(((vis > 0.05) & (vis < 0.95)).sum())

    assert penumbra(softer) > 1.5 * penumbra(base)  # the shadow's edges are wider: softer
    assert v.state()["id_conflicts"] == []  # no two widgets share an imgui ID (issue 45)
    assert v.quit() == 0


def test_placed_lights_rig_undo_redo_and_saved_rig(viewer_factory, tmp_path, headless):
    """The panel's "use rig" button adds the key light (fixed to the camera, rendered with the map's
    lights); Ctrl+Z and Ctrl+Y undo and redo it; "aim" then a click on the person turns it to face
    that point head-on; a saved rig opens again with --rig; a bad rig file is one line naming it."""
    v = viewer_factory()
    s = v.state()
    n = s["n_lights"]
    x0, y0, x1, y1 = s["widgets"]["use rig"]
    before = read_png(v.save())
    v.xdotool("mousemove", int((x0 + x1) / 2), int((y0 + y1) / 2))
    time.sleep(0.2)
    v.xdotool("click", 1)
    s_before = s
    s = v.wait_for(lambda s: len(s["placed"]) == 1, 30)
    assert s["placed"][0]["azimuth"] == 45.0
    # nothing moved under the cursor (issue 45): every widget drawn before is where it was; the
    # new light's rows are in their own box
    moved = {k: (r[1], s["widgets"][k][1]) for k, r in s_before["widgets"].items() if k in s["widgets"] and r[1] != s["widgets"][k][1]}
    assert moved == {}
    shot = v.save()
    saved = json.loads(shot.with_suffix(".json").read_text())
    assert len(saved["lights"]["lights"]) == n + 1 and saved["rig"] == s["placed"]
    changed = np.abs(read_png(shot) - before).max(axis=-1) > 4 / 255
    assert changed.mean() > 0.05  # the key light shows on the person (a fifth of the image here)
    v.xdotool("key", "ctrl+z")
    v.wait_for(lambda s: s["placed"] == [], 30)
    v.xdotool("key", "ctrl+y")
    s = v.wait_for(lambda s: len(s["placed"]) == 1, 30)
    # aim: the light then faces the clicked point of the person head-on (its direction: the normal there)
    x0, y0, x1, y1 = s["widgets"]["placed 0 aim"]
    v.xdotool("mousemove", int((x0 + x1) / 2), int((y0 + y1) / 2))
    time.sleep(0.2)
    v.xdotool("click", 1)
    v.wait_for(lambda s: s["message"].startswith("click on the person"), 30)
    scene = headless[0]
    ix, iy, iw, ih = s["image_rect"]
    col, row = next((c, r) for r in range(scene.height // 3, scene.height) for c in (scene.width // 2,) if scene.mask[r, c])
    v.xdotool("mousemove", int(ix + (col + 0.5) * iw / scene.width), int(iy + (row + 0.5) * ih / scene.height))
    time.sleep(0.2)
    v.xdotool("click", 1)
    s = v.wait_for(lambda s: "aimed" in s["message"], 30)
    from viewer.lighting.placed_lights import PlacedLight

    got = PlacedLight(**s["placed"][0]).direction
    assert s["message"].endswith(f"{col}, {row}") and np.dot(got, scene.normal[row, col]) > 0.999
    rig = tmp_path / "rig.json"
    rig.write_text(json.dumps({"format": "relight-rig", "lights": saved["rig"]}))
    assert v.state()["id_conflicts"] == []  # no two widgets share an imgui ID (issue 45)
    assert v.quit() == 0
    v.state_path.unlink()  # the next viewer writes the same state file
    again = viewer_factory("--rig", str(rig))
    again.wait_for(lambda s: s["placed"] == saved["rig"], 30)
    assert again.quit() == 0
    rig.write_text('{"format": "relight-rig", "lights": [{"kelvin": 20}]}')
    res = subprocess.run([*RELIGHT, "view", "--rig", str(rig)], capture_output=True, text=True,
                         env={**os.environ, "DISPLAY": v.display})
    assert res.returncode == 2 and str(rig) in res.stderr and "kelvin" in res.stderr and "Traceback" not in res.stderr


def test_the_users_own_lights_and_the_placed_ones_stay_where_placed(viewer_factory, tmp_path):
    """``relight view --lights FILE --rig RIG``: a light file of the user's own (no fit record: not a
    map's) opens as written, at yaw 0 (not turned by the automatic yaw); a map opened then turns its
    own brightest light to the camera, is fitted with the preset's count of lights (not the file's),
    and the rig's lights, fixed to the camera, stay where placed."""
    from viewer.lighting.placed_lights import load_rig, rig, save_rig, to_area_lights

    data = json.loads((asset_dir() / DEMO_LIGHTS).read_text())
    del data["fit"]  # the map's four brightest lights, as a file of the user's own
    data["lights"] = sorted(data["lights"], key=lambda light: -sum(light["intensity"]))[:4]
    own = tmp_path / "own.json"
    own.write_text(json.dumps(data))
    rig_file = save_rig(tmp_path / "rig.json", rig("key and fill", 1.0))
    placed = to_area_lights(load_rig(rig_file)).direction

    def rendered(v) -> np.ndarray:
        """The directions of the lights a saved frame was rendered with: the map's (or the file's), then the placed."""
        saved = json.loads(v.save().with_suffix(".json").read_text())
        return np.array([light["direction"] for light in saved["lights"]["lights"]])

    v = viewer_factory("--lights", str(own), "--rig", str(rig_file))
    s = v.wait_for(lambda s: len(s["placed"]) == 2, 30)
    assert s["look"]["yaw"] == 0.0 and abs(facing_yaw(load_lights(own))) > 90.0  # the automatic yaw would have turned them
    lights = rendered(v)
    np.testing.assert_allclose(lights[:4], load_lights(own).direction, atol=1e-5)
    np.testing.assert_allclose(lights[4:], placed, atol=1e-5)
    new_map = str(asset_dir() / "envmaps" / "venice_sunset_256.hdr")
    v.click("open a file")
    v.wait_for(lambda s: "browser path" in s["widgets"], 30)
    v.click("browser path")
    v.xdotool("type", new_map)
    v.click("browser open")
    s = v.wait_for(lambda s: s["map"] == new_map and not s["switching"] and s["message"].startswith("16 lights"), 60)
    venice = load_lights(asset_dir() / "envmaps" / "venice_sunset_256.lights.json")
    assert s["look"]["yaw"] == pytest.approx(facing_yaw(venice), abs=1e-3) and abs(s["look"]["yaw"]) > 90.0
    lights = rendered(v)
    np.testing.assert_allclose(lights[:16], venice.rotated(s["look"]["yaw"]).direction, atol=1e-4)  # the map turned
    np.testing.assert_allclose(lights[16:], placed, atol=1e-5)  # the placed lights where they were
    assert v.quit() == 0


DROP_SCRIPT = r"""
import json, sys, threading, time
from pathlib import Path
from viewer.app import ViewerConfig
from viewer.app.viewer_app import ViewerApp
from viewer.lighting.envmap import load_envmap
from viewer.scene.area_lights import load_lights
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.bundle import load_scene
from viewer.scene.resampling import resample_scene

tmp, dropped = Path(sys.argv[1]), sys.argv[2:]
maps = asset_dir() / "envmaps"
config = ViewerConfig(scene=resample_scene(load_scene(sample_scene_dir()), 128),
                      lights=load_lights(maps / "immenstadter_horn_256.lights.json"),
                      environment=load_envmap(maps / "immenstadter_horn_256.hdr").pixels,
                      env_path=maps / "immenstadter_horn_256.hdr", out_dir=tmp / "captures", state_file=tmp / "state.json",
                      max_size=256)
app = ViewerApp(config)
app.window.on_drop(app.window.handle, dropped)  # what GLFW calls when files are dropped on the window


def close_when_switched():
    end = time.monotonic() + 150
    while time.monotonic() < end:
        try:
            state = json.loads((tmp / "state.json").read_text())
            if state["map"] == dropped[0] and not state["fitting"] and state["placed"] and state["opening"] is None \
                    and state["scene_size"] != [128, 128] and not state["switching"]:
                break
        except (OSError, ValueError, KeyError):
            pass
        time.sleep(0.1)
    app.window.close()
    app.window.wake()


threading.Thread(target=close_when_switched, daemon=True).start()
sys.exit(app.run())
"""


def test_map_thumbnail_ground_shadow_and_a_bundle_from_the_browser(viewer_factory, headless):
    """A click on the map's thumbnail on a light's dot (the brightest away from the seam) adds a
    light from that direction; "aim" then another click turns it; G hides the shadow on the ground, shown by
    default since the feet are in the frame (the person's pixels stay); a scene bundle typed into the panel's
    browser opens."""
    from viewer.app.thumbnail import MapThumbnail
    from viewer.lighting.placed_lights import PlacedLight

    v = viewer_factory()

    s = v.state()
    assert s["panel_height"] <= s["window_size"][1]  # the window opens tall enough for the whole panel (1200-px screen)
    lights = load_lights(asset_dir() / DEMO_LIGHTS).rotated(s["look"]["yaw"], s["look"]["tilt"])
    uv = MapThumbnail.points(lights.direction, s["look"]["yaw"], s["look"]["tilt"])
    inner = np.nonzero((uv[:, 0] > 0.15) & (uv[:, 0] < 0.85) & (uv[:, 1] > 0.1) & (uv[:, 1] < 0.9))[0]
    k = inner[np.argmax(lights.intensity[inner].sum(axis=1))]
    sun, (u, w) = lights.direction[k], uv[k]
    s = v.click("thumbnail", u, w, until=lambda s: len(s["placed"]) == 1)
    assert "added at" in s["message"]
    assert np.degrees(np.arccos(np.clip(PlacedLight(**s["placed"][0]).direction @ sun, -1, 1))) < 2.0
    v.click("placed 0 aim", until=lambda s: s["message"].startswith("click on the person or the map"))
    s = v.click("thumbnail", 0.5, 0.9, until=lambda s: "aimed at" in s["message"])  # behind the person, low
    assert len(s["placed"]) == 1 and s["placed"][0]["elevation"] < -60
    before = read_png(v.save())
    v.xdotool("key", "g")
    v.wait_for(lambda s: s["look"]["ground"] is False, 30)
    after = read_png(v.save())
    mask = headless[0].mask
    changed = np.abs(after - before).max(axis=-1) > 4 / 255
    assert changed[~mask].sum() > 100 and not changed[mask].any()
    v.click("open a file")
    v.wait_for(lambda s: "browser path" in s["widgets"], 30)
    # a map: the panel shows it (name, thumbnail, dots) the frame the picture does, never before (issue 45)
    new_map = str(asset_dir() / "envmaps" / "venice_sunset_256.hdr")
    old_map = v.state()["shown_map"]
    v.click("browser path")
    v.xdotool("type", new_map)
    v.click("browser open")
    seen = []
    end = time.monotonic() + 60
    while time.monotonic() < end and (not seen or seen[-1]["shown_map"] != new_map):
        st = v.state()
        if st is not None:
            seen.append(st)
        time.sleep(0.02)
    assert seen[-1]["shown_map"] == new_map and seen[-1]["map"] == new_map
    assert all(st["shown_map"] in (old_map, new_map) for st in seen)
    assert not any(st["shown_map"] == new_map and st["map"] != new_map for st in seen)
    # it changed on the frame that showed the new map's picture: a "switch" among the frames drawn since the
    # state before (the state is written each frame that changes it; a poll may come a frame late)
    since = seen[-1]["frame_count"] - seen[-2]["frame_count"]
    assert seen[-2]["shown_map"] == old_map and 1 <= since <= len(seen[-1]["frames"])
    assert "switch" in [kind for _, kind in seen[-1]["frames"][-since:]]
    # while the new frame is drawn the panel holds the picture's lighting and says nothing of the new map yet
    assert all(st["held"] and not st["message"].startswith("16 lights") for st in seen if st["switching"])
    assert not seen[-1]["held"] and seen[-1]["message"].startswith("16 lights")
    v.click("browser path")
    v.xdotool("key", "ctrl+a")
    v.xdotool("type", str(sample_scene_dir()))
    v.click("browser open")
    s = v.wait_for(lambda s: s["message"].startswith("opened"), 60)
    assert "a scene bundle" in s["message"] and s["scene_size"] == [512, 512]
    assert v.state()["id_conflicts"] == []  # no two widgets share an imgui ID (issue 45)
    assert v.quit() == 0


def test_files_dropped_on_the_window_open_a_map_a_rig_and_a_photo(display, tmp_path):
    """The GLFW drop callback with real files: a map is fitted and switched to, a rig's lights are
    placed, a photo is inferred in a child process (the window drawing meanwhile) and becomes the
    person shown, and a file of another kind gets one line saying what opens."""
    import shutil

    from viewer.lighting.placed_lights import rig, save_rig

    new_map = shutil.copyfile(asset_dir() / "envmaps" / "venice_sunset_256.hdr", tmp_path / "dropped.hdr")  # no light file
    rig_file = save_rig(tmp_path / "rig.json", rig("key and fill", 1.0))
    photo = asset_dir() / "photos" / "underpass.jpg"
    notes = tmp_path / "notes.txt"
    notes.write_text("not an image")
    res = subprocess.run([sys.executable, "-c", DROP_SCRIPT, str(tmp_path), str(new_map), str(rig_file), str(photo), str(notes)],
                         env={**os.environ, "DISPLAY": display, "RELIGHT_CACHE": str(tmp_path / "cache")},
                         capture_output=True, text=True, timeout=240)
    assert res.returncode == 0, res.stderr[-2000:]
    state = json.loads((tmp_path / "state.json").read_text())
    assert state["map"] == str(new_map) and state["n_lights"] == 16
    assert state["shown_map"] == state["map"]  # the panel shows the picture's map (issue 45)
    assert len(state["placed"]) == 2 and state["placed"][1]["azimuth"] == -50.0
    assert state["scene_size"] == [170, 256] and "opened underpass.jpg (inferred now" in res.stdout
    assert str(notes) in state["error"] and "scene bundles" in state["error"]
    frames = [ms for ms, kind in state["frames"] if kind == "load"]
    assert len(frames) > 10  # the window kept drawing while the photo was inferred and the map fitted


def test_record_a_turn(viewer_factory, headless):
    v = viewer_factory("--record-frames", "12")
    v.xdotool("key", "t")
    # while it renders, its bar is over the image, whatever the window's size (issue 45)
    s = v.wait_for(lambda s: "progress" in s["widgets"] or len(s["videos"]) == 1, 120)
    if not s["videos"]:
        x, y, w, h = s["image_rect"]
        px0, py0, px1, _ = s["widgets"]["progress"]
        assert x <= px0 and px1 <= x + w and y <= py0 < y + h / 3
    s = v.wait_for(lambda s: len(s["videos"]) == 1, 120)
    v.wait_for(lambda s: "progress" not in s["widgets"], 10)  # gone once the video is written
    frames, fps = read_video(s["videos"][0])
    assert frames.shape == (12, SIZE, SIZE, 3) and fps == pytest.approx(30.0)
    # the first frame is the current view (H.264 is lossy: compare loosely)
    scene, base, engine = headless
    render_hdr(headless, FIRST_YAW)
    first = engine.output.read_display().astype(np.float32)
    assert np.abs(frames[0].astype(np.float32) - first).mean() < 3.0
    # and the turn is a turn: the last frame is 330 degrees on
    render_hdr(headless, FIRST_YAW + 330.0)
    assert np.abs(frames[-1].astype(np.float32) - engine.output.read_display()).mean() < 3.0
    assert v.state()["look"]["yaw"] == pytest.approx(FIRST_YAW)  # back where the user was
    # R records what the user does until R again, then renders it at the video's rate: the video
    # lasts as long as the interaction did, however slow a full-quality frame is
    v.xdotool("key", "r")
    s = v.wait_for(lambda s: s["recording"] is not None and s["recording"]["capturing"], 60)
    x, y, w, h = s["image_rect"]
    v.drag(int(x + w * 0.4), int(y + h * 0.5), 120, 0, steps=12)
    time.sleep(max(0.0, 2.0 - v.state()["recording"]["seconds"]))
    v.xdotool("key", "r")
    s = v.wait_for(lambda s: s["recording"] is not None and not s["recording"]["capturing"], 60)
    captured = s["recording"]["total"] / 30.0
    s = v.wait_for(lambda s: len(s["videos"]) == 2, 120)
    live, fps = read_video(s["videos"][1])
    assert captured >= 2.0 and len(live) == pytest.approx(captured * fps, abs=1)
    change = np.abs(np.diff(live.astype(np.float32), axis=0)).mean(axis=(1, 2, 3))
    assert change.max() > 1.0  # the drag turned the lighting in the video
    assert v.state()["look"]["yaw"] == pytest.approx(s["look"]["yaw"])  # the user's own turn, after the rendering
    assert v.state()["id_conflicts"] == []  # no two widgets share an imgui ID (issue 45)
    assert v.quit() == 0


def test_sigterm_while_recording_finishes_the_video(viewer_factory):
    v = viewer_factory("--record-frames", "600")
    v.xdotool("key", "t")
    s = v.wait_for(lambda s: s["recording"] is not None and s["recording"]["frames"] >= 5, 120)
    path = Path(s["recording"]["path"])
    v.proc.send_signal(signal.SIGTERM)
    assert v.proc.wait(60) == 0
    recorded = json.loads(v.state_path.read_text())["videos"]
    assert recorded == [str(path)]
    frames, _ = read_video(path)
    assert 5 <= len(frames) < 600
    assert "stopped after" in v.proc.stdout.read()


def test_a_killed_recording_is_still_playable(viewer_factory):
    v = viewer_factory("--record-frames", "600")
    v.xdotool("key", "t")
    v.wait_for(lambda s: s["recording"] is not None and s["recording"]["frames"] >= 75, 240)
    path = Path(v.state()["recording"]["path"])
    v.proc.send_signal(signal.SIGKILL)
    v.proc.wait()
    frames, _ = read_video(partial_path(path))  # the recording so far, under its partial name
    assert len(frames) >= 30 and frames.shape[1:] == (SIZE, SIZE, 3) and not path.exists()


def test_view_without_a_display_says_so(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = subprocess.run([*RELIGHT, "view", "--out-dir", str(tmp_path)], env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 2
    assert "no display" in res.stderr and "Traceback" not in res.stderr


def test_quality_preset_switches_engine_options_and_lights(viewer_factory, ctx, tmp_path):
    """Choosing the interactive preset in the panel refits its number of lights and renders with its
    engine options: the saved frame is the headless engine's with that preset."""
    from viewer.gl.presets import PRESETS

    v = viewer_factory()
    s = v.state()
    assert s["preset"] == "balanced"
    x0, y0, x1, y1 = s["widgets"]["quality"]
    v.xdotool("mousemove", int(x0 + 20), int((y0 + y1) / 2))
    time.sleep(0.2)
    v.xdotool("click", 1)
    time.sleep(0.5)
    row = list(PRESETS).index("interactive")  # the list opens under the combo, one row per preset
    v.xdotool("mousemove", int(x0 + 20), int(y1 + (y1 - y0) * (row + 0.5) + 3))
    time.sleep(0.2)
    v.xdotool("click", 1)
    p = PRESETS["interactive"]
    v.wait_for(lambda s: s["preset"] == "interactive" and s["n_lights"] == p.lights and not s["fitting"], 180)
    shot = v.save()
    saved = json.loads(shot.with_suffix(".json").read_text())
    assert saved["preset"] == "interactive"
    (tmp_path / "lights.json").write_text(json.dumps(saved["lights"]))
    lights = load_lights(tmp_path / "lights.json")
    assert len(lights) == p.lights
    scene = resample_scene(load_scene(sample_scene_dir()), SIZE)
    from viewer.lighting.envmap import load_envmap

    engine = Engine(ctx, scene, p.options)
    engine.set_environment(load_envmap(asset_dir() / "envmaps/immenstadter_horn_256.hdr").pixels)
    yaw = saved["look"]["yaw"]  # the saved lights are turned by the look's yaw (tilt 0)
    engine.set_lights(lights.rotated(-yaw))
    engine.set_look(Look(yaw=yaw))
    engine.render()
    expected = engine.output.read_output_hdr()[..., :3]
    engine.release()
    assert rel_l1(read_exr(shot.with_suffix(".exr")), expected) < 1e-3
    assert v.state()["id_conflicts"] == []  # no two widgets share an imgui ID (issue 45)
    assert v.quit() == 0


def test_the_light_count_slider_refits_the_map_when_let_go(viewer_factory):
    """The panel's "number of lights" slider keeps its value while held and refits the map's lights
    at it when let go (the panel's own state, then the refit action)."""
    v = viewer_factory()
    s = v.state()
    x0, y0, x1, y1 = s["widgets"]["number of lights"]
    before = s["n_lights"]
    v.xdotool("mousemove", int(x0 + 0.04 * (x1 - x0)), int((y0 + y1) / 2))  # near the slider's low end
    time.sleep(0.2)
    v.xdotool("click", 1)
    seen = v.wait_for(lambda s: "progress" in s["widgets"] or (s["n_lights"] != before and not s["fitting"]), 120)
    # (the message comes with the frame that shows the new lights: not switching)
    s = v.wait_for(lambda s: s["n_lights"] != before and not s["fitting"] and not s["switching"], 120)
    assert 1 <= s["n_lights"] < before and len(s["sigma"]) == s["n_lights"]
    assert "progress" in seen["widgets"] or seen["n_lights"] != before  # the fit's bar over the image, while it ran
    assert "lights (" in s["message"] and s["error"] == ""
    assert v.state()["id_conflicts"] == []  # no two widgets share an imgui ID (issue 45)
    assert v.quit() == 0


def test_a_value_typed_into_a_slider_is_that_value(viewer_factory):
    """Ctrl+click turns a slider into a text field: the typed value is the slider's, and the keys
    typed do not reach the window's shortcuts (a typed 0 reset the longitude, issue 45)."""
    v = viewer_factory()
    s = v.wait_for(lambda s: "intensity" in s["widgets"] and "longitude" in s["widgets"])
    yaw = s["look"]["yaw"]
    x0, y0, x1, y1 = s["widgets"]["intensity"]
    v.xdotool("mousemove", int((x0 + x1) / 2), int((y0 + y1) / 2))
    time.sleep(0.3)
    v.xdotool("keydown", "ctrl")
    v.xdotool("click", 1)
    v.xdotool("keyup", "ctrl")
    time.sleep(0.3)
    v.xdotool("key", "ctrl+a")
    v.xdotool("type", "0.5")
    v.xdotool("key", "Return")
    s = v.wait_for(lambda s: abs(s["look"]["intensity"] - 0.5) < 1e-6, 20)
    assert s["look"]["yaw"] == pytest.approx(yaw)  # the typed 0 did not reach the window's keys
    assert s["id_conflicts"] == []
    assert v.quit() == 0


def test_a_clip_plays_steps_and_records_every_frame_relit(viewer_factory, tmp_path, monkeypatch):
    """``relight view CLIP``: its bundle inferred (shown in the window) and a timeline: space plays the
    clip to its end at its own clock, the slider and the arrows pick a frame (one with no one in it shows
    the new background alone), a drag turns the lighting over every frame, and R records the relit clip:
    every frame, the source's timing and audio, what ``relight render --look`` of the window's state
    makes of it."""
    from test_cli import run_cli
    from test_clips import blank_frame, decoded, person_frames, write_clip

    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache" / "lights"))  # the clip's bundle cached beside it
    people = person_frames(5)
    clip = write_clip(tmp_path / "walk.mp4", people[:3] + [blank_frame()] + people[3:])
    v = viewer_factory(str(clip))
    s = v.state()
    assert s["clip"]["frames"] == 6 and s["clip"]["shown"] == [0, 0]
    v.xdotool("mousemove", 10, 10)
    v.xdotool("key", "space")
    v.wait_for(lambda s: not s["clip"]["playing"] and s["clip"]["shown"] == [5, 5], 60)  # (frames skipped as it must)
    v.click("clip every frame", fx=0.1, until=lambda s: s["clip"]["every_frame"])
    v.xdotool("mousemove", 10, 10)
    v.xdotool("key", "Home")
    v.wait_for(lambda s: s["clip"]["shown"] == [0, 0] and not s["switching"], 30)
    v.xdotool("key", "space")
    s = v.wait_for(lambda s: not s["clip"]["playing"] and s["clip"]["shown"] == [5, 5], 60)
    assert s["clip"]["played"] == 5 and s["clip"]["rate"] > 0  # every frame after the first shown, none skipped
    v.click("clip frame", fx=0.01, until=lambda s: s["clip"]["index"] == 0)
    v.xdotool("mousemove", 10, 10)
    for _ in range(2):
        v.xdotool("key", "Right")
    s = v.wait_for(lambda s: s["clip"]["shown"] == [2, 2] and not s["switching"], 30)
    x, y, w, h = s["image_rect"]
    yaw = s["look"]["yaw"]
    v.drag(int(x + w * 0.3), int(y + h * 0.5), 80, 0)
    v.wait_for(lambda s: s["look"]["yaw"] != yaw and not s["switching"], 30)
    v.xdotool("mousemove", 10, 10)
    v.xdotool("key", "Right")
    v.wait_for(lambda s: s["clip"]["shown"] == [3, 2] and not s["switching"], 30)  # no one: the person's frame before renders it
    empty = read_png(v.save())
    v.xdotool("key", "Left")
    v.wait_for(lambda s: s["clip"]["shown"] == [2, 2] and not s["switching"], 30)
    v.xdotool("key", "r")
    s = v.wait_for(lambda s: len(s["videos"]) == 1, 120)
    assert s["clip"]["index"] == 2 and s["recording"] is None  # back at the frame the user was at
    recorded, times, audio = decoded(s["videos"][0])
    source = decoded(clip)
    assert len(recorded) == 6 and times == pytest.approx(source[1]) and audio
    cli = tmp_path / "cli.mp4"
    res = run_cli("render", str(clip), "--look", str(v.state_path), "--size", str(SIZE), "-o", str(cli),
                  "--env", str(asset_dir() / "envmaps/immenstadter_horn_256.hdr"))
    assert res.returncode == 0, res.stderr
    rendered = decoded(cli)[0]
    for k in range(6):  # H.264 both ways: loosely
        assert np.abs(recorded[k].astype(np.float32) - rendered[k]).mean() < 2.0, k
    assert np.abs(recorded[3].astype(np.float32) - recorded[2]).mean() > 5.0  # the person gone
    assert np.abs(empty * 255.0 - recorded[3]).mean() < 2.0  # S saved what showed: the background alone
    assert v.quit() == 0
    # Q while a clip is being inferred in the window stops it, as Ctrl-C does (the frames done kept)
    other = write_clip(tmp_path / "other.mp4", people[::-1] + people)
    proc = subprocess.Popen([*RELIGHT, "view", str(other)], env={**os.environ, "DISPLAY": v.display, "PYTHONFAULTHANDLER": "1"},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # (a crash prints where it was)
    try:
        end = time.monotonic() + 120
        while subprocess.run(["xdotool", "search", "--name", "other.mp4"], env=v.env, capture_output=True).returncode != 0:
            assert time.monotonic() < end and proc.poll() is None
            time.sleep(0.2)
        time.sleep(1.0)
        v.xdotool("key", "q")
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == 130 and "interrupted" in err and "Traceback" not in err, (proc.returncode, err[-4000:])
    finally:
        if proc.poll() is None:
            proc.kill()


def test_a_clip_relit_ahead_plays_every_frame_at_its_rate_and_says_the_frame_on_screen(viewer_factory, tmp_path, monkeypatch):
    """A clip open in the window is relit ahead while the window is idle (a cached clip had played at 1.3
    of its frames a second, relighting each as it fell due): played, every frame shows at the clip's own
    rate. The slider and the words under it say the frame on screen whatever is asked for or coming (they
    had disagreed), and no "drawing the new light" bar shows for a clip's frame (it had, for each)."""
    import re

    from test_clips import FPS, blank_frame, person_frames, write_clip

    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache" / "lights"))
    people = person_frames(6)
    clip = write_clip(tmp_path / "walk.mp4", people[:3] + [blank_frame()] + people[3:])
    v = viewer_factory(str(clip))

    def sampled(until, timeout=60) -> list[dict]:
        """The states written until ``until`` holds (each checked: the slider and the words say the frame
        on screen, and no bar shows)."""
        states, end = [], time.monotonic() + timeout
        while time.monotonic() < end:
            s = v.state()
            if s is not None:
                states.append(s)
                c = s["clip"]
                slider, words = c["slider_and_words"]
                assert slider == int(re.search(r"frame (\d+) of", words).group(1)) == c["on_screen"] + 1, c
                assert "progress" not in s["widgets"], c
                if until(s):
                    return states
            time.sleep(0.01)
        raise AssertionError(f"timed out; last clip state: {states[-1]['clip'] if states else None}")

    v.xdotool("mousemove", 10, 10)
    v.xdotool("key", "End")  # asked for while relit: the words follow the frame on screen, not the one asked for
    sampled(lambda s: s["clip"]["on_screen"] == 6 and not s["switching"])
    v.xdotool("key", "Home")
    sampled(lambda s: s["clip"]["relit"] == 7 and s["clip"]["on_screen"] == 0 and not s["switching"], 120)
    v.xdotool("key", "space")
    states = sampled(lambda s: not s["clip"]["playing"] and s["clip"]["on_screen"] == 6)
    shown = [k for i, k in enumerate(s["clip"]["on_screen"] for s in states) if i == 0 or k != states[i - 1]["clip"]["on_screen"]]
    assert shown == list(range(7))  # every frame, in order: none skipped
    assert states[-1]["clip"]["played"] == 6 and states[-1]["clip"]["rate"] >= 0.9 * FPS
    for _ in range(3):  # stepped back while each comes in live (paused, the session brought to it)
        v.xdotool("key", "Left")
    sampled(lambda s: s["clip"]["index"] == 3 and s["clip"]["on_screen"] == 3 and s["clip"]["shown"] == [3, 2] and not s["switching"])
    # the lighting dragged: the frames relit ahead were of the lighting before, and are relit again
    x, y, w, h = v.state()["image_rect"]
    v.drag(int(x + w * 0.3), int(y + h * 0.5), 80, 0)
    sampled(lambda s: s["clip"]["relit"] < 7)
    sampled(lambda s: s["clip"]["relit"] == 7, 120)
    assert v.quit() == 0


def test_a_clip_on_a_plate_walks_across_it_and_records_as_render_makes_it(viewer_factory, tmp_path, monkeypatch):
    """``relight view CLIP --plate``: the clip's person placed once (by its first frame with them in it) and
    every frame carried into the plate alike, a frame with no one in it the plate alone; R records the
    clip on the plate at the plate's size, as ``relight render CLIP --plate`` makes it at that place."""
    from test_cli import run_cli
    from test_clips import blank_frame, decoded, person_frames, write_clip

    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache" / "lights"))
    people = person_frames(4)
    clip = write_clip(tmp_path / "walk.mp4", people[:2] + [blank_frame()] + people[2:])
    plate = street_plate(tmp_path / "street.png")
    v = viewer_factory(str(clip), "--plate", str(plate), "--horizon", "0.5")
    s = v.wait_for(lambda s: s["plate_box"] is not None and s["clip"]["shown"] == [0, 0] and not s["switching"], 60)
    first = s["plate_box"]
    v.xdotool("mousemove", 10, 10)
    v.xdotool("key", "End")
    s = v.wait_for(lambda s: s["clip"]["shown"] == [4, 4] and not s["switching"] and s["plate_box"] != first, 60)
    # the same place and scale carry the person as they moved in their frame (3 pixels a frame, to the
    # left in it): not put back where the feet were placed
    # (measured: 0.0056 of the plate to the left; placed again by each frame's own matte, the box would stay put)
    assert s["plate"]["at"] == [0.5, 0.88] and 0.003 < first[0] - s["plate_box"][0] < 0.009
    assert s["plate_box"][2] - s["plate_box"][0] == pytest.approx(first[2] - first[0], abs=0.002)
    v.xdotool("key", "Home")
    v.wait_for(lambda s: s["clip"]["shown"] == [0, 0] and not s["switching"], 60)
    for _ in range(2):
        v.xdotool("key", "Right")
    s = v.wait_for(lambda s: s["clip"]["shown"] == [2, 1] and not s["switching"], 60)  # no one in it: nobody to drag
    assert v.wait_for(lambda s: s["plate_box"] is None, 10)["plate_box"] is None
    v.xdotool("key", "Home")
    v.wait_for(lambda s: s["clip"]["shown"] == [0, 0] and not s["switching"] and s["plate_box"] is not None, 60)
    v.xdotool("key", "r")
    s = v.wait_for(lambda s: len(s["videos"]) == 1 and s["recording"] is None, 180)
    recorded, _, _ = decoded(s["videos"][0])
    assert len(recorded) == 5 and recorded[0].shape == (320, 480, 3)
    assert np.abs(recorded[2].astype(np.float32) - read_png(plate) * 255.0).mean() < 2.0  # no one: the plate alone
    cli = tmp_path / "cli.mp4"
    place = v.state()["plate"]  # (their feet are cut by their frame: --height places them anyway, as the window does)
    res = run_cli("render", str(clip), "--look", str(v.state_path), "--size", str(SIZE), "--plate", str(plate), "--horizon", "0.5",
                  "--at=" + ",".join(f"{c:.6f}" for c in place["at"]), "--height", str(place["height"]), "-o", str(cli))
    assert res.returncode == 0, res.stderr
    rendered = decoded(cli)[0]

    def differing(a, b) -> float:  # the share of pixels more than 20 levels apart (the person is ~2 % of the plate)
        return float((np.abs(a.astype(np.float32) - b).max(axis=-1) > 20).mean())

    plate_px = read_png(plate) * 255.0
    for k in range(5):  # H.264 both ways, and the grain render gives the person: to a few levels, and no pixel far off
        assert np.abs(recorded[k].astype(np.float32) - rendered[k]).mean() < 2.0 and differing(recorded[k], rendered[k]) < 0.001, k
        assert (differing(recorded[k], plate_px) > 0.008) == (k != 2), k  # the person in every frame but the empty one
    assert np.abs(recorded[1].astype(np.float32) - recorded[2]).mean() > 0.5  # the person gone
    # another plate opened from the panel while the clip is open: the clip's person on it, placed the same way
    other = open_from_browser(v, street_plate(tmp_path / "dusk.png", 400, 300, sky=(0.9, 0.5, 0.3), ground=(0.2, 0.18, 0.2)))
    s = v.wait_for(lambda s: s["plate"]["source"] == str(other) and s["plate_box"] is not None and not s["fitting"], 60)
    assert s["clip"]["frames"] == 5 and s["error"] == ""
    # another person (a scene bundle) opened: the clip goes, and they are placed by their own frame (feet where placed)
    open_from_browser(v, sample_scene_dir(), plate=False)
    s = v.wait_for(lambda s: s["clip"] is None and s["plate_box"] is not None and not s["switching"], 60)
    s = v.wait_for(lambda s: s["plate_box"][2] - s["plate_box"][0] > 0.09, 30)  # (the new person's, wider than the clip's)
    x0, y0, x1, y1 = s["plate_box"]  # their feet at the place and as tall as it says (the clip's matte placed them lower, taller)
    assert abs(y1 - s["plate"]["at"][1]) < 0.002 and abs((y1 - y0) - s["plate"]["height"]) < 0.005, s["plate_box"]
    assert s["plate"]["source"] == str(other)
    assert v.quit() == 0


def open_from_browser(v, path: Path, plate: bool = True) -> Path:
    """``path`` opened from the panel's file browser (opened if it is not), as the plate (with "the next photo
    opened is the plate" ticked) or as the person."""
    if "browser path" not in v.state()["widgets"]:
        v.click("open a file")
        v.wait_for(lambda s: "browser path" in s["widgets"], 30)
    if plate:
        v.click("plate next")
    v.click("browser path")
    v.xdotool("type", str(path))
    v.click("browser open")
    return path


def street_plate(path: Path, width: int = 480, height: int = 320, sky=(0.55, 0.7, 0.9), ground=(0.35, 0.33, 0.3)) -> Path:
    """A plate made here: a sky over a textured ground meeting at the middle, a few dark poles."""
    from viewer.files.imageio import write_png

    rng = np.random.default_rng(3)
    img = np.empty((height, width, 3), np.float32)
    img[: height // 2] = sky
    img[height // 2:] = ground
    img[height // 2:] += rng.normal(0.0, 0.03, (height - height // 2, width, 1))
    for x in range(40, width, 110):
        img[height // 4:height * 3 // 4, x:x + 4] = 0.1
    write_png(path, np.clip(img, 0.0, 1.0))
    return path


def test_a_person_moved_and_scaled_on_a_plate_and_saved_as_render_makes_it(viewer_factory, tmp_path):
    """``relight view --plate``: the person stands where the feet go by default, a drag on them moves
    them (a drag off them turns the lighting), the wheel scales them about their feet, S writes the
    composite at the plate's size as ``relight render --plate`` makes it at that place (to a level),
    with the layers; a photo opened with "the next photo opened is the plate" becomes the plate, and
    the plate can be removed."""
    import OpenEXR

    plate = street_plate(tmp_path / "street.png")
    v = viewer_factory("--plate", str(plate), "--horizon", "0.5", "--record-frames", "3")
    s = v.wait_for(lambda s: s["plate_box"] is not None)
    assert s["plate"]["at"] == [0.5, 0.88] and abs(s["plate"]["height"] - 0.38 * 1.7 / 1.6) < 1e-5
    assert s["plate"]["light"] == "plate" and s["look"]["yaw"] == 0.0 and s["look"]["exposure"] == 0.0
    x, y, w, h = s["image_rect"]
    assert abs(w / h - 480 / 320) < 0.01  # the plate is what the window shows
    x0, y0, x1, y1 = s["plate_box"]  # fractions of the plate
    assert abs(0.5 * (x0 + x1) - 0.5) < 0.05 and abs(y1 - 0.88) < 0.01  # the feet where they stand
    assert any("35 mm" in n for n in s["plate_notes"])  # what reading the plate said (no EXIF: 35 mm taken)
    v.drag(int(x + w * 0.5 * (x0 + x1)), int(y + h * 0.5 * (y0 + y1)), -100, 0)
    s = v.wait_for(lambda s: s["plate"]["at"][0] < 0.45 and s["plate_box"][0] < x0 - 10 / 480)
    assert abs(s["plate"]["at"][0] - (0.5 - 100 / w)) < 0.01 and abs(s["plate"]["at"][1] - 0.88) < 0.01
    assert s["look"]["yaw"] == 0.0  # the person moved, the lighting did not turn
    height = s["plate"]["height"]
    x0, y0, x1, y1 = s["plate_box"]
    v.drag(int(x + w * 0.5 * (x0 + x1)), int(y + h * 0.5 * (y0 + y1)), 0, -40)  # farther away: smaller, on the ground
    s = v.wait_for(lambda s: s["plate"]["at"][1] < 0.86)
    below = s["plate"]["at"][1] - 0.5
    assert s["plate"]["height"] == pytest.approx(height * below / 0.38, rel=1e-4)
    v.drag(int(x + 0.9 * w), int(y + 0.1 * h), -60, 0)  # off the person: the lighting turns
    s = v.wait_for(lambda s: s["look"]["yaw"] != 0.0)
    height, exposure = s["plate"]["height"], s["look"]["exposure"]
    v.xdotool("mousemove", int(x + 0.9 * w), int(y + 0.5 * h))  # the wheel off the person: the exposure, as anywhere
    v.xdotool("click", 4)
    s = v.wait_for(lambda s: s["look"]["exposure"] != exposure)
    assert s["plate"]["height"] == height
    x0, y0, x1, y1 = s["plate_box"]
    v.xdotool("mousemove", int(x + w * 0.5 * (x0 + x1)), int(y + h * 0.5 * (y0 + y1)))  # on the person: scaled
    v.xdotool("click", 4)
    v.xdotool("click", 4)
    s = v.wait_for(lambda s: s["plate"]["height"] > height * 1.06 ** 2 - 1e-6)
    assert abs(s["plate"]["height"] - height * 1.06 ** 2) < 1e-5 and "of the plate tall" in s["message"]
    saved = v.save()
    place = json.loads(saved.with_suffix(".json").read_text())
    assert place["plate"] == s["plate"]
    at = ",".join(f"{c:.6f}" for c in place["plate"]["at"])
    out = tmp_path / "rendered.png"
    subprocess.run([*RELIGHT, "render", str(sample_scene_dir()), "--size", str(SIZE), "--plate", str(plate), "--at=" + at,
                    "--height", str(place["plate"]["height"]), "--horizon", "0.5", "--look", str(saved.with_suffix(".json")),
                    "-o", str(out)], env=v.env, check=True, capture_output=True)  # (the saved look: its turn and exposure)
    mine, theirs = read_png(saved), read_png(out)
    assert mine.shape == (320, 480, 3) and np.abs(mine - theirs).max() <= 1.5 / 255  # what render makes, to a level
    assert np.abs(mine - read_png(plate)).max() > 0.2  # the person is in it
    layers = OpenEXR.File(str(saved.with_suffix(".exr"))).channels()
    assert {"person", "shadow", "plate"} <= set(layers)
    v.xdotool("key", "t")  # a turn recorded on the plate: the plate with the person in it, the plate's size
    s = v.wait_for(lambda s: len(s["videos"]) == 1 and s["recording"] is None, 120)
    frames, _ = read_video(s["videos"][0])
    assert frames.shape == (3, 320, 480, 3)
    first = frames[0].astype(np.float32) / 255.0
    assert np.abs(first - mine).mean() < 3.0 / 255.0  # the saved composite (H.264: loosely)
    assert (np.abs(first - mine).max(axis=-1) > 20 / 255).mean() < 0.005  # no part of it far off (measured 0.1 %)
    assert (np.abs(first - read_png(plate)).max(axis=-1) > 20 / 255).mean() > 0.007  # the person in it (measured 1.5 %)
    other = open_from_browser(v, street_plate(tmp_path / "dusk.png", 360, 360, sky=(0.9, 0.5, 0.3), ground=(0.2, 0.18, 0.2)))
    s = v.wait_for(lambda s: s["plate"]["source"] == str(other) and not s["fitting"] and s["shown_map"] == s["map"], 60)
    assert s["plate"]["light"] == "plate" and s["scene_size"] == [SIZE, SIZE] and "dusk-light-" in s["map"]
    s = v.click("remove the plate", until=lambda s: s["plate"] is None)
    assert s["look"]["background"] != "transparent"  # the person in their frame again
    assert v.quit() == 0


def test_what_the_user_marks_in_front_hides_the_person_in_the_window_too(viewer_factory, tmp_path):
    """``relight view --plate P --front MASK``: the window's composite hides the person behind what the mask
    marks (a thin post over where they stand by default), as ``relight render --plate`` does; the saved
    composite is the plate there and shows the person beside it."""
    from PIL import Image

    plate = street_plate(tmp_path / "street.png")
    mask = np.zeros((320, 480), np.uint8)
    mask[:, 236:245] = 255  # a post through the middle, over the person's default place
    Image.fromarray(mask).save(tmp_path / "post.png")
    v = viewer_factory("--plate", str(plate), "--horizon", "0.5", "--front", str(tmp_path / "post.png"))
    s = v.wait_for(lambda s: s["plate_box"] is not None)
    x0, _, x1, _ = s["plate_box"]
    assert x0 < 236 / 480 and x1 > 245 / 480  # the person stands behind the post
    saved, shown = read_png(v.save()), read_png(plate)
    post = np.zeros((320, 480), bool)
    post[:, 239:242] = True  # (its refined edge, 2 px, left out)
    assert np.abs(saved - shown)[post].max() <= 1.5 / 255  # the plate where the post is
    beside = np.zeros((320, 480), bool)
    beside[:, 248:int(x1 * 480)] = True
    assert (np.abs(saved - shown).max(axis=-1)[beside] > 0.1).sum() > 20  # the person beside it
    assert v.quit() == 0
