"""The command line: the demo writes real files; bad input is one clear line, not a traceback."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from viewer.cli.main import main
from viewer.files.imageio import read_exr, read_png
from viewer.lab.bench.metrics import detail_kept
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.bundle import load_scene


def test_demo_writes_png_and_exr(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    png, exr = tmp_path / "demo.png", tmp_path / "demo.exr"
    assert str(png) in out and str(exr) in out
    img, hdr = read_png(png), read_exr(exr)
    assert img.shape == (512, 512, 3) and hdr.shape == (512, 512, 3)
    assert np.isfinite(hdr).all() and hdr.max() > 0.05  # lit, not a silent black image
    assert img.std() > 0.05
    assert (tmp_path / "demo_passes.png").is_file()
    # the whole path on the bundled photo (automatic mask): inferred, then relit at the photo's own
    # size under each bundled map (refined shadows), with the photo's detail
    assert "inferred the scene bundle of photos/underpass.jpg (automatic mask)" in out
    bundle = load_scene(tmp_path / "photo_bundle")
    w, h = 681, 1024  # the bundled photo's size
    assert bundle.output_size == (w, h) and bundle.frame.alpha.mean() > 0.05
    sheet = read_png(tmp_path / "photo_relit.png")
    assert sheet.shape == (h, 4 * w, 3)
    photo, relit = sheet[:, :w], [sheet[:, k * w:(k + 1) * w] for k in range(1, 4)]
    m = bundle.frame.alpha > 0.5
    for a in relit:
        assert a[m].std() > 0.02  # lit, with shading
        assert 0.7 < detail_kept(a, photo, m) < 1.3  # the photo's own detail, not a blur
    assert np.abs(relit[0][m] - relit[1][m]).mean() > 0.02  # different maps, different pictures


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "viewer.cli.main", *args], capture_output=True, text=True)


def test_bad_inputs_give_one_line_errors(tmp_path):
    bad_lights = tmp_path / "lights.json"
    bad_lights.write_text('{"format": "relight-lights", "lights": [{"direction": [0, 2, 0], "sigma": 1, "intensity": [1, 1, 1]}]}')
    from viewer.resources import sample_scene_dir

    for args, message in (
        (("render", str(tmp_path / "nope"), str(bad_lights)), "scene bundle directory not found"),
        (("render", str(sample_scene_dir()), str(bad_lights)), "not a unit vector"),
        (("render", str(sample_scene_dir()), str(tmp_path / "missing.json")), "light file not found"),
    ):
        res = run_cli(*args)
        assert res.returncode == 2, res.stderr
        assert "Traceback" not in res.stderr
        assert message in res.stderr and res.stderr.startswith("relight: error: ")


def test_viewing_precomputed_maps_never_imports_torch(tmp_path):
    """Rendering a scene bundle under a light file (what the demo does after inference) needs no torch."""
    from viewer.cli.commands import DEMO_ENVMAP, DEMO_LIGHTS
    from viewer.resources import asset_dir, sample_scene_dir

    args = [str(sample_scene_dir()), str(asset_dir() / DEMO_LIGHTS), "--env", str(asset_dir() / DEMO_ENVMAP),
            "-o", str(tmp_path / "x.png")]
    code = ("import sys; from viewer.cli.main import main; assert main(['render', *sys.argv[1:]]) == 0;"
            "assert 'torch' not in sys.modules, 'torch was imported'")
    res = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def test_fit_lights_writes_lights_and_picture_and_caches(tmp_path):
    import json
    import os

    from viewer.resources import asset_dir

    env = asset_dir() / "envmaps" / "immenstadter_horn_256.hdr"
    out, plot = tmp_path / "lights.json", tmp_path / "lights.png"
    environ = dict(os.environ, RELIGHT_CACHE=str(tmp_path / "cache"))
    args = [sys.executable, "-m", "viewer.cli.main", "fit-lights", str(env), "-n", "4", "-o", str(out), "--plot", str(plot)]
    first = subprocess.run(args, capture_output=True, text=True, env=environ)
    assert first.returncode == 0, first.stderr
    assert "fitted in" in first.stdout
    data = json.loads(out.read_text())
    assert len(data["lights"]) == 4 and set(data["lights"][0]) == {"direction", "sigma", "intensity"}
    assert read_png(plot).std() > 0.05
    again = subprocess.run(args, capture_output=True, text=True, env=environ)
    assert again.returncode == 0 and "from the cache" in again.stdout
    # the render command fits (here: finds in the cache) the lights of a map given without a light file
    from viewer.resources import sample_scene_dir

    res = subprocess.run([sys.executable, "-m", "viewer.cli.main", "render", str(sample_scene_dir()), "--envmap", str(env),
                          "-n", "4", "-o", str(tmp_path / "r.png"), "--yaw", "90"], capture_output=True, text=True,
                         env=environ)
    assert res.returncode == 0, res.stderr
    assert f"4 lights for {env}: from the cache" in res.stdout
    assert read_exr(tmp_path / "r.exr").max() > 0.05
    # without -o the light file goes beside the map, where the viewer looks for it (not into the
    # working folder); a stage of the fit that ran is one line on a log (stderr is not a terminal)
    import shutil

    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.map_lights import sidecar_lights

    (tmp_path / "maps").mkdir()
    (tmp_path / "work").mkdir()
    mine = shutil.copyfile(env, tmp_path / "maps" / env.name)
    res = subprocess.run([sys.executable, "-m", "viewer.cli.main", "fit-lights", str(mine), "-n", "4", "--refit"],
                         capture_output=True, text=True, env=environ, cwd=tmp_path / "work")
    assert res.returncode == 0, res.stderr
    assert not any((tmp_path / "work").iterdir()) and f"-> {mine.with_suffix('.lights.json')}" in res.stdout
    assert sidecar_lights(load_envmap(mine), mine, 4, "instant") is not None  # the default method wrote it
    assert "fitting 4 lights to" in res.stderr and " in " in res.stderr.splitlines()[-1]


def test_fit_lights_bad_maps_give_one_line_errors(tmp_path):
    import cv2

    from viewer.files.imageio import write_exr

    nan_map = np.ones((8, 16, 3), np.float32)
    nan_map[2, 3] = np.nan
    write_exr(tmp_path / "nan.exr", nan_map)
    cv2.imwrite(str(tmp_path / "square.hdr"), np.ones((8, 8, 3), np.float32))
    for name, message in (("nan.exr", "NaN or Inf"), ("square.hdr", "2:1 aspect"), ("missing.hdr", "environment map not found")):
        res = run_cli("fit-lights", str(tmp_path / name), "-o", str(tmp_path / "l.json"))
        assert res.returncode == 2 and "Traceback" not in res.stderr
        assert message in res.stderr and str(tmp_path / name) in res.stderr
    black = tmp_path / "black.hdr"
    cv2.imwrite(str(black), np.zeros((8, 16, 3), np.float32))
    res = run_cli("fit-lights", str(black), "-n", "2", "-o", str(tmp_path / "b.json"), "--method", "median-cut")
    assert res.returncode == 0 and "black" in res.stderr


def test_benchmarks_leave_the_checkout_clean(tmp_path):
    """A benchmark without -o writes under out/ of the working folder, never into docs/."""
    res = subprocess.run([sys.executable, "-m", "viewer.cli.main", "bench", "engine", "--sizes", "64", "--lights", "8",
                          "--repeats", "1", "--no-twin"], capture_output=True, text=True, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file()) == ["out/bench_engine.json"]


def test_a_file_of_the_wrong_kind_is_one_line_saying_what_it_is(tmp_path):
    from viewer.lighting.placed_lights import rig, save_rig
    from viewer.scene.area_lights import AreaLights

    notes = tmp_path / "notes.txt"
    notes.write_text("not a photo\n")
    lights = AreaLights(np.array([[0.0, 1.0, 0.0]]), [1.0], [[1.0, 1.0, 1.0]]).save(tmp_path / "l.json")
    rig_file = save_rig(tmp_path / "rig.json", rig("key", 1.0))
    look = tmp_path / "capture.json"
    look.write_text(json.dumps({"look": {"yaw": 10}}))
    empty = tmp_path / "empty"
    empty.mkdir()
    env = str(asset_dir() / "envmaps" / "venice_sunset_256.hdr")
    for given, words in ((notes, "is a text file"), (Path(env), "is an environment map, not a photo"),
                         (lights, "is a light file"), (rig_file, "is a rig"), (look, "is a saved look"),
                         (empty, "scene.json")):
        for argv in (("infer", str(given), "-o", str(tmp_path / "b")), ("render", str(given), "--env", env, "-o",
                                                                           str(tmp_path / "x.png"))):
            res = run_cli(*argv)
            assert res.returncode == 2, (argv, res.stderr)
            line = res.stderr.strip()
            assert "\n" not in line and words in line and str(given) in line, (argv, line)
    assert "--env" in run_cli("render", env, "-o", str(tmp_path / "x.png")).stderr


def test_a_device_the_machine_lacks_is_named_not_the_weights(tmp_path):
    photo = asset_dir() / "photos" / "underpass.jpg"
    for device, words in (("bogus", "not a device torch knows"), ("mps", "run on cpu or cuda")):
        res = run_cli("infer", str(photo), "-o", str(tmp_path / "b"), "--device", device)
        assert res.returncode == 2 and words in res.stderr and "--device" in res.stderr, res.stderr
        assert "safetensors" not in res.stderr and res.stderr.count("\n") == 1
    assert not (tmp_path / "b").exists()


def test_work_past_the_memory_and_time_budgets_is_refused_before_it_starts(tmp_path):
    """Sizes asked for that would not fit (a render at --size 8192 with its frame, was killed by the
    kernel at 23.6 GB; `fast` with 256 lights took 197 s and 9 GB; a card describing 40 GB of weights
    thrashed the machine): one line, at once, saying what would fit."""
    import re
    import shutil
    import time

    from viewer.resources import network_dir, sample_scene_dir

    nets = tmp_path / "nets"
    shutil.copytree(network_dir(), nets)
    card = json.loads((nets / "inverse.json").read_text())
    card["model"].update(width=256, levels=8)
    (nets / "inverse.json").write_text(json.dumps(card))
    env = asset_dir() / "envmaps" / "venice_sunset_256.hdr"
    photo = asset_dir() / "photos" / "underpass.jpg"
    for args, said in (
        (("render", sample_scene_dir(), "--env", env, "--size", "8192", "--max-size", "16384", "-o", tmp_path / "x.png"),
         r"rendering maps of 8192 px would need about \d+\.\d GB of memory, more than the \d+\.\d GB this machine can "
         r"give now \(--size \d+ or less fits\)"),
        (("fit-lights", env, "-n", "300", "-o", tmp_path / "l.json"),
         r"-n: the number of lights must be in \[1, 256\], got 300"),
        (("render", sample_scene_dir(), "--env", env, "-n", "65", "--method", "paper", "-o", tmp_path / "y.png"),
         "--method paper fits at most 64 lights"),
        (("infer", photo, "--size", "64", "--networks", nets, "-o", tmp_path / "b"),
         "inverse.json: the card describes another network than inverse.safetensors holds"),
    ):
        start = time.monotonic()
        res = run_cli(*map(str, args))
        lines = res.stderr.strip().splitlines()
        assert res.returncode == 2 and len(lines) == 1, res.stderr
        assert re.search(said, lines[0]), lines[0]
        assert time.monotonic() - start < 30
    assert not any(tmp_path.glob("[xyb]*")) and not (tmp_path / "l.json").exists()


def test_the_render_estimate_holds_the_largest_size_it_offers_within_the_budget():
    from viewer import memory_needs

    for aspect, frame in ((1.0, 0), (0.665, 1362 * 2048), (0.3, 4096 * 4096)):
        side = memory_needs.largest_render_size(aspect, frame)
        assert memory_needs.render_bytes(side * side * aspect, frame) <= memory_needs.memory_budget()
        assert memory_needs.render_bytes((side + 256) ** 2 * aspect, frame) > memory_needs.memory_budget() or side >= 8192


def test_a_photo_whose_frame_would_not_fit_memory_is_refused_from_its_header(tmp_path):
    """A 12000x8011 photo at --max-size 12000 was killed by the kernel at 24.4 GB: the frame's
    memory is estimated from the photo's header and the command refused at once, saying what fits."""
    import re

    from PIL import Image

    from viewer import memory_needs

    photo = tmp_path / "wide.png"
    Image.new("RGB", (16000, 10000), (90, 80, 70)).save(photo)  # 16000x10000: 120 MB decoded, a few KB on disk
    res = run_cli("infer", str(photo), "--max-size", "16384", "-o", str(tmp_path / "b"))
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    side = int(re.search(r"--max-size (\d+) or less fits", lines[0]).group(1))
    assert lines[0].startswith(f"relight: error: {photo}: a 16000x10000 frame from this photo would need about")
    assert memory_needs.infer_bytes(16000 * 10000, side * side * 10000 // 16000) <= memory_needs.memory_budget()
    assert not (tmp_path / "b").exists()


def test_closed_full_or_abandoned_output_streams_never_stop_the_work(tmp_path):
    """stdout closed (``>&-``), a full device (``>/dev/full``), a reader that leaves (``| head -1``)
    and every standard stream closed: the render is written, exit 0; a full stdout is one warning
    line, a closed one says nothing (issue 43)."""
    import shlex

    lights = asset_dir() / "envmaps" / "venice_sunset_256.lights.json"
    base = " ".join(shlex.quote(a) for a in (sys.executable, "-m", "viewer.cli.main", "render", str(sample_scene_dir()), str(lights),
                                                 "--size", "64", "-o"))
    for k, redirect in enumerate((">&-", ">/dev/full", "| head -1", "2>&- >&- <&-")):
        out = tmp_path / f"r{k}.png"
        res = subprocess.run(["bash", "-o", "pipefail", "-c", f"{base} {shlex.quote(str(out))} {redirect}"],
                             capture_output=True, text=True, timeout=300)
        assert res.returncode == 0 and out.is_file(), (redirect, res.stderr)
        assert "Traceback" not in res.stderr
        if redirect == ">/dev/full":
            assert res.stderr.strip().splitlines()[-1].startswith("relight: warning: standard output refused its lines")


def test_render_turns_the_map_as_view_and_batch_do(tmp_path):
    """render's default yaw is the automatic one (issue 44): the map's brightest light on the
    camera's side, as the window and batch open; --yaw 0 gives the old default's picture."""
    from viewer.scene.area_lights import facing_yaw, load_lights

    env = asset_dir() / "envmaps" / "venice_sunset_256.hdr"
    common = ["render", str(sample_scene_dir()), "--env", str(env), "--size", "96", "--max-size", "192"]
    yaw = facing_yaw(load_lights(env.with_suffix(".lights.json")))  # the 16 lights shipped beside the map
    assert abs(yaw) > 1.0
    pictures = {}
    for name, extra in (("auto", []), ("given", ["--yaw", str(yaw)]), ("zero", ["--yaw", "0"])):
        assert main([*common, *extra, "-o", str(tmp_path / f"{name}.png")]) == 0
        pictures[name] = read_png(tmp_path / f"{name}.png")
    np.testing.assert_array_equal(pictures["auto"], pictures["given"])
    assert np.abs(pictures["auto"] - pictures["zero"]).mean() > 0.01


def key_light_file(path: Path, degrees: float = 60.0) -> Path:
    """A light file of the user's own: one key light ``degrees`` to the camera's right, a little above,
    written as by hand (no fit record: not a map's lights)."""
    a = np.radians(degrees)
    d = np.array([np.sin(a), 0.3, np.cos(a)])
    path.write_text(json.dumps({"format": "relight-lights", "version": 1, "lights": [
        {"direction": (d / np.linalg.norm(d)).tolist(), "sigma": 4.0, "intensity": [6.0, 6.0, 6.0]}]}))
    return path


def test_placed_lights_stay_where_placed(tmp_path):
    """A light file of the user's own is where they put it: no --yaw is --yaw 0 (the picture the same to the
    bit), with a rig beside it and with a map behind it; the automatic yaw would have turned its key light to
    the front (another picture). A light file fitted to a map (its fit record names the map) is that map's
    lights: turned as the map is."""
    from viewer.lighting.placed_lights import rig, save_rig
    from viewer.scene.area_lights import facing_yaw, load_lights

    own = key_light_file(tmp_path / "key.json")
    rig_file = save_rig(tmp_path / "rig.json", rig("rim", 1.0))
    fitted = asset_dir() / "envmaps" / "venice_sunset_256.lights.json"  # relight fit-lights' record: the map's lights
    turned = facing_yaw(load_lights(own))  # what the automatic yaw would turn the key light by
    assert abs(turned + 60.0) < 1.0
    scene, size = str(sample_scene_dir()), ["--size", "96", "--max-size", "192"]
    looks = {"own": [str(own)], "own_rig": [str(own), "--rig", str(rig_file)],
             "own_map": [str(own), "--env", str(asset_dir() / "envmaps" / "studio_small_03_256.hdr")]}
    for name, given in looks.items():
        pictures = {}
        for yaw, extra in (("none", []), ("zero", ["--yaw=0"]), ("turned", [f"--yaw={turned}"])):
            assert main(["render", scene, *given, *size, *extra, "-o", str(tmp_path / f"{name}_{yaw}.png")]) == 0
            pictures[yaw] = read_png(tmp_path / f"{name}_{yaw}.png")
        np.testing.assert_array_equal(pictures["none"], pictures["zero"], err_msg=name)
        assert np.abs(pictures["turned"] - pictures["zero"]).mean() > 0.01, name  # the key light in front: it shows
    pictures = {}
    for yaw, extra in (("none", []), ("facing", [f"--yaw={facing_yaw(load_lights(fitted))}"]), ("zero", ["--yaw=0"])):
        assert main(["render", scene, str(fitted), *size, *extra, "-o", str(tmp_path / f"fitted_{yaw}.png")]) == 0
        pictures[yaw] = read_png(tmp_path / f"fitted_{yaw}.png")
    np.testing.assert_array_equal(pictures["none"], pictures["facing"])
    assert np.abs(pictures["none"] - pictures["zero"]).mean() > 0.01
