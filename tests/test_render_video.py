"""Headless frames and turntable videos (``relight render``), temporal stability, the video writer
and the viewer's input mapping (no window needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from viewer.app import interaction as ix
from viewer.cli.main import main
from viewer.errors import InputError
from viewer.files.imageio import read_exr, read_png
from viewer.gl import Engine, EngineOptions
from viewer.output.render import render_turntable, turntable_yaws
from viewer.output.temporal import drmse, flicker_ratio
from viewer.output.video import VideoWriter, read_video
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.area_lights import load_lights
from viewer.scene.bundle import load_scene
from viewer.scene.look import EXPOSURE_LIMIT, Look
from viewer.scene.resampling import resample_scene

DATA = Path(__file__).parent / "data"
MAP = asset_dir() / "envmaps/immenstadter_horn_256.hdr"
LIGHTS = asset_dir() / "envmaps/immenstadter_horn_256.lights.json"


def test_render_matches_the_stored_reference_image(tmp_path):
    """tests/data/render_yaw210.png was written by the command below (again when the default tone curve
    became the neutral one, issue 59); a change to the engine that moves the picture shows here."""
    out = tmp_path / "frame.png"
    assert main(["render", str(sample_scene_dir()), str(LIGHTS), "--env", str(MAP), "--rotate", "210", "--size", "256",
                 "--out", str(out)]) == 0
    got = read_png(out) * 255.0
    ref = read_png(DATA / "render_yaw210.png") * 255.0
    diff = np.abs(got - ref)
    assert diff.mean() < 0.5 and np.percentile(diff, 99.9) <= 4.0


def test_render_turntable_video_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "turn.mp4"
    assert main(["render", str(sample_scene_dir()), str(LIGHTS), "--env", str(MAP), "--frames", "8", "--fps", "24",
                 "--size", "128", "--out", str(out)]) == 0
    assert f"wrote {out} (8 frames, 128x128, 24 fps" in capsys.readouterr().out
    frames, fps = read_video(out)
    assert frames.shape == (8, 128, 128, 3) and fps == pytest.approx(24.0)
    assert np.abs(np.diff(frames.astype(np.float32), axis=0)).mean() > 1.0  # the lighting turns
    assert main(["render", str(sample_scene_dir()), str(LIGHTS), "--frames", "8", "--out", str(tmp_path / "x.png")]) == 2
    assert main(["render", str(sample_scene_dir()), str(LIGHTS), "--out", str(tmp_path / "x.gif")]) == 2


def test_turntable_is_temporally_stable(ctx, tmp_path):
    """32 frames of a full turn on the sample (256 px): frame-to-frame change follows the
    converged engine's (shadow maps 1024, full-resolution mesh, 8 Fourier terms), i.e. no flicker
    beyond what the rotation causes; and the video holds those frames."""
    scene = resample_scene(load_scene(sample_scene_dir()), 256)
    lights = load_lights(LIGHTS)

    def frames(options):
        eng = Engine(ctx, scene, options)
        out = []
        for yaw in turntable_yaws(180.0, 360.0, 32):
            eng.set_lights(lights)
            eng.set_look(Look(yaw=float(yaw), background="color"))
            eng.render()
            out.append(eng.output.read_display().astype(np.float32) / 255.0)
        eng.release()
        return np.stack(out)

    default = frames(EngineOptions())
    reference = frames(EngineOptions(shadow_resolution=1024, shadow_step=1, terms=8))
    d = drmse(default, reference)
    assert d[1] < 0.006 and d[2] < 0.008 and d[4] < 0.01
    assert flicker_ratio(default) < 1.1 * flicker_ratio(reference)
    # flicker is what these measures catch: the same frames with 1 % noise fail both
    noisy = default + np.random.default_rng(0).normal(0.0, 0.01, default.shape)
    assert drmse(noisy, reference)[1] > 0.01 and flicker_ratio(noisy) > 2 * flicker_ratio(reference)

    eng = Engine(ctx, scene, EngineOptions())
    path = tmp_path / "t.mp4"
    assert render_turntable(eng, lights, path, Look(yaw=180.0, background="color"), 32) == (256, 256)
    eng.release()
    video, _ = read_video(path)
    assert video.shape == (32, 256, 256, 3)
    assert np.abs(video.astype(np.float32) / 255.0 - default).mean() < 0.01  # H.264 at CRF 18


def test_video_writer(tmp_path):
    with VideoWriter(tmp_path / "odd.mp4", 33, 21, fps=10) as v:  # an odd last row / column is left out for 4:2:0
        for i in range(5):
            v.write(np.full((21, 33, 3), i / 5.0, np.float32))
        with pytest.raises(ValueError):
            v.write(np.zeros((20, 33, 3), np.uint8))
    frames, fps = read_video(tmp_path / "odd.mp4")
    assert frames.shape == (5, 20, 32, 3) and fps == pytest.approx(10.0)  # cropped, never padded
    assert np.abs(frames.mean(axis=(1, 2, 3)) - np.arange(5) / 5.0 * 255).max() < 3
    with pytest.raises(InputError):
        VideoWriter(tmp_path / "x.avi", 8, 8)
    # live timing: frames at wall-clock times keep their spacing
    with VideoWriter(tmp_path / "live.mp4", 16, 16, fps=30) as v:
        for t in (0.0, 0.5, 0.6, 2.0):
            v.write(np.zeros((16, 16, 3), np.uint8), seconds=t)
    import av

    with av.open(str(tmp_path / "live.mp4")) as c:
        times = [float(f.time) for f in c.decode(video=0)]
    np.testing.assert_allclose(times, [0.0, 0.5, 0.6, 2.0], atol=1e-3)


def test_drag_and_wheel_mapping():
    s = Look(yaw=10.0)
    # dragging right turns a point in front of the camera to the right: yaw decreases
    assert ix.dragged(s, 20, 0).yaw == pytest.approx(10.0 - 20 * ix.DEGREES_PER_PIXEL)
    assert ix.dragged(s, 0, -1000).tilt == 90.0 and ix.dragged(s, 0, 1000).tilt == -90.0
    assert -180.0 <= ix.dragged(s, 10000, 0).yaw < 180.0
    assert ix.wheeled(s, 2).exposure == pytest.approx(2 * ix.EXPOSURE_PER_NOTCH)
    assert ix.wheeled(s, 1e6).exposure == EXPOSURE_LIMIT and ix.wheeled(s, -1e6).exposure == -EXPOSURE_LIMIT
    # zooming keeps the image point under the cursor in place
    area = (400, 300)
    cursor = (300.0, 100.0)
    before = ix.image_rect((512, 512), area)
    z = ix.zoomed(ix.ViewState(), 3, cursor=cursor, area=area)
    after = ix.image_rect((512, 512), area, z.zoom, z.pan)
    u = ((cursor[0] - before[0]) / before[2], (cursor[1] - before[1]) / before[3])
    assert after[0] + u[0] * after[2] == pytest.approx(cursor[0]) and after[1] + u[1] * after[3] == pytest.approx(cursor[1])
    assert ix.image_rect((512, 256), (400, 400)) == (0.0, 100.0, 400.0, 200.0)


def test_video_writer_reports_an_encoder_failure(tmp_path):
    """A failing encoder makes close() raise (it neither hangs nor reports success); a disk's failure is one line
    naming the video (issue 62: a traceback before)."""
    import threading

    from viewer.errors import InputError

    v = VideoWriter(tmp_path / "fail.mp4", 16, 16)
    v.write(np.zeros((16, 16, 3), np.uint8))

    class Failing:
        def __init__(self, stream):
            self.stream = stream

        def encode(self, frame=None):
            raise OSError("disk full")

    v._stream = Failing(v._stream)
    errors = []

    def close():
        try:
            v.close()
        except InputError as exc:
            errors.append(str(exc))

    t = threading.Thread(target=close, daemon=True)
    t.start()
    t.join(20)
    assert not t.is_alive() and errors and errors[0] == f"{tmp_path / 'fail.mp4'}: cannot write the video (disk full)"


def test_passes_sheet_without_shadows(tmp_path):
    """--visibility none renders no shadows, but the passes sheet still shows both visibilities."""
    out = tmp_path / "flat.png"
    assert main(["render", str(sample_scene_dir()), str(LIGHTS), "--visibility", "none", "--size", "128",
                 "--out", str(out)]) == 0
    sheet = read_png(tmp_path / "flat_passes.png")
    h = sheet.shape[0] // 2
    w = sheet.shape[1] // 4
    for i in range(3):  # soft shadows, hard shadows, shading: none of them black
        assert sheet[h + 20:, i * w:(i + 1) * w].mean() > 0.02


def test_the_temporal_benchmarks_turn_renders(ctx, monkeypatch):
    """``relight bench temporal``'s turntable (a few frames of it): it renders through the product's look."""
    import viewer.lab.bench.temporal as temporal

    monkeypatch.setattr(temporal, "FRAMES", 4)
    scene = resample_scene(load_scene(sample_scene_dir()), 64)
    frames, ms = temporal._turn(ctx, scene, load_lights(asset_dir() / "envmaps" / "venice_sunset_256.lights.json"),
                                EngineOptions(shadow_resolution=128), "soft")
    assert frames.shape == (4, 64, 64, 3) and ms > 0 and frames.std(axis=0).mean() > 1e-3  # the light turns


def test_render_with_a_rig_adds_its_lights_fixed_to_the_camera(tmp_path, capsys):
    """relight render --rig: the placed lights light the person as well as the map's, and a turn of
    the map leaves them where they are; a bad rig is one line naming it."""
    from viewer.lighting.placed_lights import rig, save_rig

    path = save_rig(tmp_path / "rig.json", rig("rim", 2.0))
    base = [str(sample_scene_dir()), str(LIGHTS), "--env", str(MAP), "--size", "128", "--no-ground"]
    assert main(["render", *base, "--out", str(tmp_path / "plain.png")]) == 0
    assert main(["render", *base, "--rig", str(path), "--out", str(tmp_path / "rim.png")]) == 0
    plain, rim = read_exr(tmp_path / "plain.exr"), read_exr(tmp_path / "rim.exr")
    assert (rim >= plain - 1e-4).all() and (rim - plain).max() > 0.05  # light added, none taken away
    assert main(["render", *base, "--rig", str(path), "--yaw", "90", "--out", str(tmp_path / "turned.png")]) == 0
    assert main(["render", *base, "--yaw", "90", "--out", str(tmp_path / "turned_plain.png")]) == 0
    added = read_exr(tmp_path / "turned.exr") - read_exr(tmp_path / "turned_plain.exr")
    np.testing.assert_allclose(added, rim - plain, atol=2e-3)  # the rim light did not turn with the map
    (tmp_path / "bad.json").write_text("[1, 2]")
    capsys.readouterr()
    assert main(["render", *base, "--rig", str(tmp_path / "bad.json"), "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert "not a rig" in err and str(tmp_path / "bad.json") in err and "Traceback" not in err
