"""Clips in, relit clips out (issue 46, step 1): decoding any clip PyAV reads (rotation, variable
frame rate, damaged packets), the clip bundle written frame by frame and resumed, the relit MP4
with the source's timing and audio, resumed from its parts, and one line for bad input."""

from __future__ import annotations

import contextlib
import json
import shutil
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_DATA

from viewer.errors import InputError, NoPersonError
from viewer.files.imageio import read_png
from viewer.resources import asset_dir

FPS = 10


def person_frames(count: int, width: int = 320, height: int = 480) -> list[np.ndarray]:
    """The bundled photo's person, a window moved 3 pixels a frame (a real person, small and fast)."""
    from viewer.photo.frames import read_photo
    from viewer.resize import resize

    photo = read_photo(asset_dir() / "photos/underpass.jpg", [])
    scale = 1.05 * height / photo.shape[0]
    big = resize(photo, (round(photo.shape[1] * scale), round(photo.shape[0] * scale)))
    x0 = (big.shape[1] - width) // 2 - 4
    return [np.ascontiguousarray(big[:height, x0 + 3 * i:x0 + 3 * i + width]) for i in range(count)]


def blank_frame(width: int = 320, height: int = 480) -> np.ndarray:
    """A wall with no one in front of it."""
    rng = np.random.default_rng(3)
    return np.clip(150 + rng.normal(0, 6, (height, width, 3)), 0, 255).astype(np.uint8)


def write_clip(path, frames, times=None, rotation=0, audio="aac", video="libx264", container=None, gop=None, sar=None):
    """A clip of ``frames`` (RGB uint8) at ``times`` (seconds; default 1 / FPS apart), the display
    matrix turned ``rotation`` degrees, and one second of a 440 Hz tone in ``audio`` (None: silent);
    ``sar``: its pixels' aspect (a Fraction: width over height)."""
    import av

    with av.open(str(path), "w", format=container) as c:
        stream = c.add_stream(video, rate=FPS)
        stream.height, stream.width = frames[0].shape[:2]
        stream.pix_fmt = "yuv420p"
        stream.codec_context.time_base = Fraction(1, 1000)
        if gop is not None:
            stream.codec_context.gop_size = gop
        if sar is not None:
            stream.codec_context.sample_aspect_ratio = sar
        if rotation:
            stream.set_display_rotation(rotation)
        sound = None
        if audio is not None:
            sound = c.add_stream(audio, rate=44100)
            sound.layout = "mono"
        times = [i / FPS for i in range(len(frames))] if times is None else times
        for rgb, t in zip(frames, times, strict=True):
            frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
            frame.pts, frame.time_base = int(round(t * 1000)), Fraction(1, 1000)
            for packet in stream.encode(frame):
                c.mux(packet)
        for packet in stream.encode():
            c.mux(packet)
        if sound is not None:
            fmt = sound.codec_context.codec.audio_formats[0].name
            total = int(44100 * (times[-1] + 1 / FPS))
            for k in range(0, total, 1024):
                wave = 0.3 * np.sin(2 * np.pi * 440 * np.arange(k, min(k + 1024, total)) / 44100)[None]
                data = (wave * 30000).astype(np.int16) if fmt.startswith("s16") else wave.astype(np.float32)
                frame = av.AudioFrame.from_ndarray(data, format=fmt, layout="mono")
                frame.sample_rate, frame.pts = 44100, k
                for packet in sound.encode(frame):
                    c.mux(packet)
            for packet in sound.encode():
                c.mux(packet)
    return Path(path)


def pattern(i: int, width: int = 64, height: int = 48) -> np.ndarray:
    """A frame whose brightness says its index, a white block at the top left."""
    rgb = np.full((height, width, 3), 20 + 15 * i, np.uint8)
    rgb[:8, :8] = 255
    return rgb


def audio_times(path) -> list[float]:
    """The times of a file's audio packets."""
    import av

    with av.open(str(path)) as c:
        return [float(p.pts * p.time_base) for p in c.demux(audio=0) if p.size] if c.streams.audio else []


def decoded(path) -> tuple[list[np.ndarray], list[float], list]:
    """(frames, their times, the audio packets' times) of a video file."""
    import av

    with av.open(str(path)) as c:
        frames, times = [], []
        for f in c.decode(video=0):
            frames.append(f.to_ndarray(format="rgb24"))
            times.append(float(f.time))
    return frames, times, audio_times(path)


# --- reading clips ------------------------------------------------------------------------------
def test_frames_come_upright_with_their_own_times(tmp_path):
    """A phone's sideways clip comes out as a player shows it; a variable frame rate keeps each
    frame's time; --start / --end choose frames by time."""
    from viewer.files.clip_reader import clip_frames, probe_clip

    times = [0.0, 0.1, 0.35, 0.4, 0.9]
    clip = write_clip(tmp_path / "phone.mp4", [pattern(i) for i in range(5)], times, rotation=90)
    info = probe_clip(clip)
    assert (info.width, info.height, info.rotation, info.audio) == (48, 64, 90, "aac")
    frames = list(clip_frames(clip))
    assert [round(f.seconds, 3) for f in frames] == times
    first = frames[0].rgb
    assert first.shape == (64, 48, 3)
    ys, xs = np.nonzero(first[..., 0] > 200)  # the top-left block, turned a quarter counter-clockwise
    assert ys.min() > 48 and xs.max() < 10
    assert np.all(np.diff([int(f.rgb[30, 30, 0]) for f in frames]) > 8)  # each frame its own, in order
    part = list(clip_frames(clip, start=0.3, end=0.9))
    assert [round(f.seconds + f.at, 3) for f in part] == [0.35, 0.4] and part[0].seconds == 0.0


def test_damaged_packets_keep_the_frame_count(tmp_path):
    """A packet that does not decode is one warning line and a lost frame in its place; a file cut
    short ends the clip at its last whole frame, with a warning."""
    import av

    from viewer.files.clip_reader import clip_frames

    clip = write_clip(tmp_path / "clip.mp4", [pattern(i) for i in range(12)], audio=None, gop=1)
    with av.open(str(clip)) as c:
        packets = [(p.pos, p.size) for p in c.demux(video=0) if p.size]
    data = bytearray(clip.read_bytes())
    pos, size = packets[5]
    data[pos:pos + 4] = (size * 50).to_bytes(4, "big")  # the NAL's length: far past the packet
    damaged = tmp_path / "damaged.mp4"
    damaged.write_bytes(bytes(data))
    with pytest.warns(UserWarning, match=r"damaged\.mp4: a damaged packet at 0\.500 s did not decode"):
        frames = list(clip_frames(damaged))
    assert len(frames) == 12 and [f.index for f in frames] == list(range(12))
    assert frames[5].rgb is None and all(f.rgb is not None for i, f in enumerate(frames) if i != 5)
    assert [round(f.seconds, 3) for f in frames] == [round(i / FPS, 3) for i in range(12)]

    # an MP4 whose index is at its end, cut: nothing to read, one line
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(clip.read_bytes()[: packets[8][0] + 3])
    with pytest.raises(InputError, match="cut.mp4: is not a video this program can read"):
        list(clip_frames(cut))
    # a stream cut mid-packet (Matroska): the frames before the cut
    streamed = write_clip(tmp_path / "clip.mkv", [pattern(i) for i in range(12)], audio=None, gop=1)
    with av.open(str(streamed)) as c:
        at = [p.pos for p in c.demux(video=0) if p.size][8]
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(streamed.read_bytes()[:at + 40])
    frames = list(clip_frames(cut))
    assert 7 <= len(frames) <= 9 and all(f.rgb is not None for f in frames[:7])


def test_bad_clips_are_one_line(tmp_path):
    from viewer.files.clip_reader import clip_frames, probe_clip

    text = tmp_path / "notes.mp4"
    text.write_text("not a video")
    with pytest.raises(InputError, match="notes.mp4: is not a video this program can read"):
        probe_clip(text)
    import av

    sound = tmp_path / "sound.mkv"
    with av.open(str(sound), "w") as c:
        s = c.add_stream("aac", rate=44100)
        s.layout = "mono"
        frame = av.AudioFrame.from_ndarray(np.zeros((1, 1024), np.float32), format="fltp", layout="mono")
        frame.sample_rate, frame.pts = 44100, 0
        for p in [*s.encode(frame), *s.encode()]:
            c.mux(p)
    with pytest.raises(InputError, match="sound.mkv: holds no video stream"):
        probe_clip(sound)
    clip = write_clip(tmp_path / "clip.mp4", [pattern(i) for i in range(6)], audio=None)
    with pytest.raises(InputError, match="6 frames .* more than the 4 one run takes"):
        next(clip_frames(clip, limit=4))
    with pytest.raises(InputError, match="--end must come after --start"):
        next(clip_frames(clip, start=0.5, end=0.2))
    with pytest.raises(InputError, match="holds no frame from 3 s"):
        next(clip_frames(clip, start=3.0))


# --- the clip bundle and the relit clip -----------------------------------------------------------
@pytest.fixture(scope="module")
def clip_with_everything(tmp_path_factory):
    """Five frames at 10 fps with a tone: the person, a damaged packet, an empty wall (a cut), the
    person twice (one shot)."""
    import av

    folder = tmp_path_factory.mktemp("clip")
    people = person_frames(4)
    clip = write_clip(folder / "walk.mp4", [people[0], people[1], blank_frame(), people[2], people[3]], gop=1)
    with av.open(str(clip)) as c:
        pos, size = [(p.pos, p.size) for p in c.demux(video=0) if p.size][1]
    data = bytearray(clip.read_bytes())
    data[pos:pos + 4] = (size * 50).to_bytes(4, "big")
    clip.write_bytes(bytes(data))
    return clip


@pytest.fixture(scope="module")
def clip_bundle(clip_with_everything, tmp_path_factory):
    from viewer.photo.clip_inference import infer_clip

    out = tmp_path_factory.mktemp("bundle") / "walk"
    with pytest.warns(UserWarning, match="damaged packet"):
        record = infer_clip(clip_with_everything, out)
    return out, record


def test_a_clip_bundle_holds_every_frame_and_resumes(clip_bundle, clip_with_everything):
    from viewer.photo.clip_cache import ClipRequest, clip_target
    from viewer.photo.clip_inference import infer_clip
    from viewer.scene.bundle import load_scene
    from viewer.scene.clip_bundle import load_clip_bundle

    out, record = clip_bundle
    assert record["complete"] and record["frames"] == 5 and record["temporal"] == "on"
    assert record["states"] == {"person": 3, "no person": 1, "lost": 1}
    bundle = load_clip_bundle(out)
    assert [e.state for e in bundle.frames] == ["person", "lost", "no person", "person", "person"]
    assert [round(e.seconds, 3) for e in bundle.frames] == [0.0, 0.1, 0.2, 0.3, 0.4]
    assert [e.shot for e in bundle.frames] == [0, 0, 1, 2, 2] and record["shots"] == 3  # the wall is a cut, each way
    scene = load_scene(bundle.scene_path(3))
    assert scene.output_size == (320, 480) and scene.frame.alpha.mean() > 0.05
    inference = json.loads((bundle.scene_path(4) / "inference.json").read_text())
    assert inference["clip"]["index"] == 4 and inference["photo"].endswith("walk.mp4 at 0.400 s")
    # one light per shot: frame 4 was given the light fitted on frame 3
    lights = [json.loads((bundle.scene_path(i) / "lights.json").read_text())["lights"] for i in (0, 3, 4)]
    assert lights[2] == lights[1] and lights[1] != lights[0] and "given" in inference["photo_lighting"]
    # frame 4's maps carried from frame 3's along the flow; frame 3 starts its shot afresh
    share = {i: json.loads((bundle.scene_path(i) / "inference.json").read_text())["steady_share"] for i in (0, 3, 4)}
    assert share[0] == 0.0 and share[3] == 0.0 and share[4] > 0.5, share
    # the clip's window slides 3 px a frame (a pan): the old background's content moves 3 px left
    assert bundle.frames[3].pan == (0.0, 0.0) and abs(bundle.frames[4].pan[0] + 3.0) < 0.5 and abs(bundle.frames[4].pan[1]) < 0.5

    # a run that stopped before frame 4's record: the same command keeps the others and does frame
    # 4 again, given its shot's light from frame 3's bundle
    (out / "frames" / "000004.json").unlink()
    with pytest.warns(UserWarning, match="damaged packet"):
        again = infer_clip(clip_with_everything, out)
    assert again["frames_kept_from_earlier_run"] == 4 and again["states"] == record["states"]
    assert load_clip_bundle(out).frames == bundle.frames
    assert json.loads((bundle.scene_path(4) / "lights.json").read_text())["lights"] == lights[1]
    again4 = json.loads((bundle.scene_path(4) / "inference.json").read_text())["steady_share"]
    assert again4 == share[4]  # steadied from frame 3's maps as written, as the unbroken run did
    # --temporal off: every frame its own estimates, as a photo
    off = infer_clip(clip_with_everything, out.parent / "off", request=ClipRequest(end=0.05, temporal="off"))
    assert off["temporal"] == "off" and off["frames"] == 1 and off["shots"] is None
    # a folder with the user's files in it is not a place for a clip bundle
    mine = out.parent / "mine"
    mine.mkdir()
    (mine / "thesis.txt").write_text("mine")
    with pytest.raises(InputError, match="files relight did not write"):
        clip_target(mine)
    assert (mine / "thesis.txt").read_text() == "mine"


def test_the_relit_clip_keeps_frames_timing_and_sound(clip_bundle, clip_with_everything, ctx, tmp_path):
    """Same frames and times as the source, its AAC sound copied; the lost frame shows the one
    before it, the empty frame the new background alone; a stopped render goes on from its parts."""
    from viewer.gl import EngineOptions
    from viewer.lighting.envmap import load_envmap
    from viewer.output import clip_render
    from viewer.scene.area_lights import load_lights
    from viewer.scene.clip_bundle import load_clip_bundle
    from viewer.scene.look import Look

    bundle = load_clip_bundle(clip_bundle[0])
    env = load_envmap(asset_dir() / "envmaps/immenstadter_horn_256.hdr")
    lights = load_lights(asset_dir() / "envmaps/immenstadter_horn_256.lights.json")
    look = Look(yaw=180.0, exposure="auto")
    pictures = clip_render.ClipPictures(ctx, bundle, lights, look, env.pixels, None, EngineOptions())
    try:
        frames = [pictures.picture(i).astype(np.float32) for i in range(5)]
        alpha = pictures.frames.scene(0).frame.alpha
    finally:
        pictures.release()
    assert np.array_equal(frames[1], frames[0])  # lost: the frame before
    assert pictures.frames.background_camera(4) == pictures.frames.background_camera(3)  # one lens for the map behind a shot
    assert set(pictures._exposures) == {0, 2}  # one exposure per shot with a person
    import cv2

    near = cv2.dilate((alpha > 0.02).astype(np.uint8), np.ones((41, 41), np.uint8)) > 0
    away = ~near
    away[int(0.8 * away.shape[0]):] = False  # the ground, where the person's shadow falls
    assert np.abs(frames[2] - frames[0])[away].mean() < 2.0  # the same background
    assert np.abs(frames[2] - frames[0])[alpha > 0.9].mean() > 15.0  # and no one in front of it
    assert frames[2].std() > 5.0  # a picture, not a black frame
    photo_look = clip_render.ClipPictures(ctx, bundle, lights, look.replace(background="photo"), env.pixels, None, EngineOptions())
    try:  # the old background kept: where no one is, the frame itself
        kept = photo_look.picture(2).astype(np.float32)  # (the clip's H.264 greyed the wall's colour noise)
        assert np.abs(kept.mean(axis=(0, 1)) - blank_frame().mean(axis=(0, 1))).max() < 3.0
        assert np.abs(kept - frames[2]).mean() > 10.0 and kept.std() < 15.0
    finally:
        photo_look.release()

    out = tmp_path / "relit.mp4"
    stops = {"after": 3}

    def stop_once(done, total):
        if done == stops["after"]:
            stops["after"] = None
            raise KeyboardInterrupt

    saved = clip_render.PART_SECONDS
    clip_render.PART_SECONDS = 0.2  # parts of two frames
    try:
        with pytest.raises(KeyboardInterrupt):
            clip_render.render_clip(clip_render.ClipPictures(ctx, bundle, lights, look, env.pixels, None, EngineOptions()), out,
                                    progress=stop_once)
        assert not out.exists() and (clip_render.parts_folder(out) / "000000.mp4").is_file()
        result = clip_render.render_clip(clip_render.ClipPictures(ctx, bundle, lights, look, env.pixels, None, EngineOptions()), out)
    finally:
        clip_render.PART_SECONDS = saved
    assert result["parts_reused"] == 1 and result["audio_note"] is None
    assert not clip_render.parts_folder(out).exists()
    video, times, audio = decoded(out)
    source_audio = audio_times(clip_with_everything)
    assert len(video) == 5 and np.allclose(times, [0.0, 0.1, 0.2, 0.3, 0.4], atol=1e-3)
    assert audio and len(audio) >= len(source_audio) - 2 and max(audio) < 0.5
    assert all(np.abs(v.astype(np.float32) - f).mean() < 3.0 for v, f in zip(video, frames, strict=True))


def test_audio_an_mp4_cannot_hold_goes_beside_it(tmp_path):
    import av

    from viewer.output.video import VideoWriter, audio_sidecar, join_clip

    source = write_clip(tmp_path / "old.avi", [pattern(i) for i in range(3)], audio="adpcm_ima_wav", video="mpeg4")
    part = tmp_path / "part.mp4"
    with VideoWriter(part, 64, 48, fps=FPS) as video:
        for i in range(3):
            video.write(pattern(i), seconds=i / FPS)
    out = tmp_path / "relit.mp4"
    note = join_clip([(part, 0.0)], out, source, 0.0, 0.3)
    sidecar = audio_sidecar(out, source)
    assert note is not None and str(sidecar) in note and "adpcm_ima_wav" in note
    with av.open(str(sidecar)) as c:
        assert c.streams.audio[0].codec_context.name == "adpcm_ima_wav"
        assert sum(1 for p in c.demux(audio=0) if p.size) > 0
    assert len(decoded(out)[0]) == 3 and decoded(out)[2] == []


def test_clip_commands(clip_bundle, clip_with_everything, tmp_path):
    """The command line: a clip bundle relit to MP4; what does not fit a clip is one line."""
    from test_cli import run_cli

    out = tmp_path / "relit.mp4"
    env = str(asset_dir() / "envmaps/immenstadter_horn_256.hdr")
    res = run_cli("render", str(clip_bundle[0]), "--env", env, "-o", str(out), "--turn", "90")
    assert res.returncode == 0, res.stderr
    assert f"wrote {out} (5 frames, 320x480" in res.stdout
    frames, times, audio = decoded(out)
    assert len(frames) == 5 and audio
    assert np.abs(frames[4].astype(float) - frames[0].astype(float)).mean() > 3  # the map turned
    for args, message in (
        (("render", str(clip_bundle[0]), "--env", env, "-o", str(tmp_path / "a.png")), "give a .mp4 output path"),
        (("render", str(clip_bundle[0]), "--env", env, "-o", str(tmp_path / "b.mp4"), "--frames", "10"),
         "a clip keeps its own frames"),
        (("render", str(clip_bundle[0]), "--env", env, "-o", str(tmp_path / "c.mp4"), "--end", "0.2"),
         "give the clip itself"),
        (("render", str(clip_bundle[0]), "--env", env, "-o", str(tmp_path / "c.mp4"), "--temporal", "off"),
         "give the clip itself"),
        (("infer", str(asset_dir() / "photos/underpass.jpg"), "-o", str(tmp_path / "d"), "--start", "1"),
         "choose a part of a clip: this is not one"),
        (("infer", str(clip_with_everything), "-o", str(tmp_path / "e"), "--mask", "m.png"), "a mask is for a photo"),
        (("view", str(clip_with_everything), "--mask", "m.png"), "--mask needs a photo"),
        (("view", str(clip_bundle[0]), "--end", "0.2"), "give the clip itself"),
        (("view", str(asset_dir() / "sample_scene"), "--start", "1"), "choose a part of a clip: this is not one"),
        (("render", str(asset_dir() / "sample_scene"), "--env", env, "-o", str(tmp_path / "f.png"), "--layers"),
         "for a photo's, use relight batch --layers"),
    ):
        res = run_cli(*args)
        assert res.returncode == 2 and message in res.stderr, (args, res.stderr)
        assert "Traceback" not in res.stderr
    shutil.rmtree(tmp_path / "d", ignore_errors=True)


def test_a_clip_lit_by_the_users_own_lights_is_not_turned(clip_bundle, tmp_path):
    """``relight render CLIP_BUNDLE LIGHTS.json``: a light file of the user's own stays where they put it
    (no --yaw is --yaw 0, every frame to the bit); turned as the automatic yaw would, it is another clip."""
    from test_cli import key_light_file

    from viewer.cli.main import main
    from viewer.scene.area_lights import facing_yaw, load_lights

    own = key_light_file(tmp_path / "key.json")
    clips = {}
    for yaw, extra in (("none", []), ("zero", ["--yaw=0"]), ("turned", [f"--yaw={facing_yaw(load_lights(own))}"])):
        assert main(["render", str(clip_bundle[0]), str(own), *extra, "-o", str(tmp_path / f"{yaw}.mp4")]) == 0
        clips[yaw] = np.stack(decoded(tmp_path / f"{yaw}.mp4")[0]).astype(np.int16)
    np.testing.assert_array_equal(clips["none"], clips["zero"])
    assert np.abs(clips["turned"] - clips["zero"]).max() > 20


def test_a_clip_put_into_a_plate_walks_across_it(clip_bundle, tmp_path):
    """``relight render CLIP_BUNDLE --plate PLATE``: every frame the plate's size with the person in it,
    placed once (on the first frame with them) so they move across the plate as across their frame
    (the window 3 pixels a frame: left, by 9 frame pixels times the scale from frame 0 to 4), the frame
    with no one the plate alone; a clip's layers on a plate are refused in one line."""
    from test_cli import run_cli

    from viewer.files.imageio import write_png

    rng = np.random.default_rng(4)
    plate = np.empty((320, 480, 3), np.float32)
    plate[:150] = (0.6, 0.7, 0.85)
    plate[150:] = np.clip(0.4 + rng.normal(0.0, 0.02, (170, 480, 1)), 0.0, 1.0)
    write_png(tmp_path / "square.png", plate)
    out = tmp_path / "on_square.mp4"
    res = run_cli("render", str(clip_bundle[0]), "--plate", str(tmp_path / "square.png"), "--at", "0.4,0.95", "--height", "0.6",
                  "--horizon", "0.47", "-o", str(out))
    assert res.returncode == 0, res.stderr
    assert f"wrote {out} (5 frames, 480x320" in res.stdout
    frames, _, audio = decoded(out)
    back = read_png(tmp_path / "square.png") * 255.0
    assert len(frames) == 5 and audio
    assert np.abs(frames[2].astype(float) - back).mean() < 2.0  # no one: the plate (to the video's coding)
    centres = []
    for k in (0, 4):
        person = np.abs(frames[k].astype(float) - back).max(axis=-1) > 40
        rows, cols = np.nonzero(person)
        assert 0.5 * 0.6 * 320 < rows.max() - rows.min() < 1.1 * 0.6 * 320 and abs(rows.max() + 1 - 0.95 * 320) < 6
        centres.append(cols.mean())
    scale = 0.6 * 320 / (0.9 * 480)  # the plate's pixels a frame pixel (the person ~0.9 of their 480-px frame)
    assert 0.4 * 9 * scale < centres[0] - centres[1] < 2.5 * 9 * scale
    res = run_cli("render", str(clip_bundle[0]), "--plate", str(tmp_path / "square.png"), "--height", "0.6", "--layers",
                  "-o", str(tmp_path / "x.mp4"))
    assert res.returncode == 2 and "a clip on a plate has none yet" in res.stderr


def test_a_relit_clips_layers_are_an_exr_sequence(clip_bundle, tmp_path):
    """``--layers``: an EXR per frame beside the MP4, its beauty the MP4's frame; a lost frame's are the
    frame before's, a frame with no person has the background alone; run again, the layers are kept;
    a foreign file in the folder is refused before any work."""
    import OpenEXR
    from test_cli import run_cli

    out = tmp_path / "relit.mp4"
    env = str(asset_dir() / "envmaps/immenstadter_horn_256.hdr")
    res = run_cli("render", str(clip_bundle[0]), "--env", env, "-o", str(out), "--layers")
    assert res.returncode == 0, res.stderr
    folder = tmp_path / "relit.layers"
    assert f"wrote {folder}/ (5 frames' layers" in res.stdout
    assert sorted(p.name for p in folder.iterdir()) == [f"{i:06d}.exr" for i in range(5)] + ["layers.json"]

    def layers(i):
        with OpenEXR.File(str(folder / f"{i:06d}.exr"), separate_channels=True) as f:
            return {name: np.asarray(c.pixels, np.float32) for name, c in f.channels().items()}

    frames = [layers(i) for i in range(5)]
    assert all(set(f) == set(frames[0]) for f in frames) and frames[0]["R"].shape == (480, 320)
    assert frames[0]["person.A"].mean() > 0.05 and frames[2]["person.A"].max() == 0.0 and frames[2]["diffuse.G"].max() == 0.0
    assert np.array_equal(frames[1]["R"], frames[0]["R"])  # the lost frame shows the frame before
    assert frames[2]["G"].mean() > 0.01 and np.all(np.isfinite(frames[2]["G"]))  # the new background
    video, _, _ = decoded(out)
    beauty = np.stack([frames[3][c] for c in "RGB"], -1)
    assert np.corrcoef(beauty.mean(-1).ravel(), video[3].mean(-1).ravel())[0, 1] > 0.9
    stamps = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    out.unlink()
    res = run_cli("render", str(clip_bundle[0]), "--env", env, "-o", str(out), "--layers")
    assert res.returncode == 0 and {p.name: p.stat().st_mtime_ns for p in folder.iterdir()} == stamps, res.stderr
    (folder / "notes.txt").write_text("mine")
    out.unlink()
    res = run_cli("render", str(clip_bundle[0]), "--env", env, "-o", str(out), "--layers")
    assert res.returncode == 2 and "relit.layers: is not a folder of layers relight wrote" in res.stderr
    assert (folder / "notes.txt").read_text() == "mine" and not out.exists()


def test_a_stopped_clip_render_goes_on_when_run_again(clip_bundle, tmp_path):
    """A render stopped (SIGTERM) while its parts folder is there: the same command again finishes."""
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "relit.mp4"
    cmd = [sys.executable, "-m", "viewer.cli.main", "render", str(clip_bundle[0]), "--env",
           str(asset_dir() / "envmaps/immenstadter_horn_256.hdr"), "-o", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (tmp_path / "relit.parts").is_dir() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=120)
    assert (tmp_path / "relit.parts").is_dir() and not out.exists()
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert len(decoded(out)[0]) == 5 and not (tmp_path / "relit.parts").exists()


def test_a_clip_relit_as_it_is_inferred_is_the_same_to_the_bit(tmp_path, monkeypatch, capsys):
    """``relight render CLIP`` relights each frame as soon as its inference (a child process) has made
    it final: the first frames, with no one in them, wait for the first person; parts of two frames
    are written while the inference goes on. The MP4 is the one the bundle relit whole afterwards
    gives, byte for byte. A parent killed outright takes its child with it (the bundle's lock is free
    at once) and the same command goes on from the frames and parts it left; a clip with no one in it
    is one line."""
    import signal
    import subprocess
    import sys

    from viewer.cli.main import main
    from viewer.output import clip_render

    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache" / "lights"))
    monkeypatch.setattr(clip_render, "PART_SECONDS", 0.2)
    people = person_frames(4)
    clip = write_clip(tmp_path / "walk.mp4", [blank_frame(), blank_frame(), people[0], people[1], people[2], people[3]])
    env = str(asset_dir() / "envmaps/immenstadter_horn_256.hdr")
    assert main(["render", str(clip), "--env", env, "-o", str(tmp_path / "followed.mp4")]) == 0
    said = capsys.readouterr().out
    assert "(6 frames, 320x480" in said and "inferred and relit together" in said, said
    assert "6 frames: 4 with the person, 2 without" in said
    assert main(["render", str(clip), "--env", env, "-o", str(tmp_path / "whole.mp4")]) == 0
    said = capsys.readouterr().out
    assert "(6 frames, 320x480" in said and "inferred and relit together" not in said, said
    assert (tmp_path / "followed.mp4").read_bytes() == (tmp_path / "whole.mp4").read_bytes()
    frames, _, audio = decoded(tmp_path / "followed.mp4")
    assert len(frames) == 6 and audio

    # stopped (SIGTERM) once a frame is in: one line at once, then killed outright (SIGKILL: no handler
    # runs) at the next: the child goes with it both times
    other = write_clip(tmp_path / "other.mp4", person_frames(5))
    out = tmp_path / "killed.mp4"
    cmd = [sys.executable, "-m", "viewer.cli.main", "render", str(other), "--env", env, "-o", str(out)]
    for frame, stop in (("000000", signal.SIGTERM), ("000001", signal.SIGKILL)):
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 300
        while not list((tmp_path / "cache").glob(f"bundles/other-*/frames/{frame}.json")) and time.monotonic() < deadline \
                and proc.poll() is None:
            time.sleep(0.05)
        stopped = time.monotonic()
        proc.send_signal(stop)
        _, err = proc.communicate(timeout=60)
        if stop == signal.SIGTERM:
            assert proc.returncode == 130 and "relight: interrupted (SIGTERM)" in err and "Traceback" not in err, err
            assert time.monotonic() - stopped < 10  # not at the child's next word
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    kept = int(res.stdout.split(" kept from an earlier run")[0].rsplit("; ", 1)[1])
    assert kept >= 2, res.stdout
    assert len(decoded(out)[0]) == 5

    empty = write_clip(tmp_path / "empty.mp4", [blank_frame()] * 3)
    assert main(["render", str(empty), "--env", env, "-o", str(tmp_path / "empty_relit.mp4")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "empty.mp4" in err and "Traceback" not in err, err


def test_a_clip_inferred_in_ranges_joins_without_a_seam(tmp_path):
    """A panning clip inferred whole, and in two ranges (the later one run first, as a worker may, so
    its overlap is inferred, not read; then the batch stops, and ``relight render CLIP``'s inference
    finishes the bundle range by range): the same shots, frames and lights; the steadied maps at the
    join within a hundredth of the whole run's (the overlap's filter has forgotten where it began);
    the pans joined within a pixel; the offset kept in the record. One run at a time makes a bundle."""
    import json as js

    from viewer.files.ownership import folder_lock
    from viewer.photo.clip_inference import infer_clip
    from viewer.photo.clip_ranges import ClipRange, infer_range, open_ranges
    from viewer.scene.bundle import load_scene
    from viewer.scene.clip_bundle import load_clip_bundle

    clip = write_clip(tmp_path / "pan.mp4", person_frames(10, 160, 240), audio=None)
    infer_clip(clip, tmp_path / "whole")
    bundle = open_ranges(clip, tmp_path / "ranges", 2, overlap=2)
    out = bundle.path
    assert bundle.earlier is None and [r.to_json() for r in bundle.ranges] == [[0, 6, 0], [6, 10, 2]]
    with pytest.raises(InputError, match="another relight is making this clip bundle now"):
        infer_clip(clip, out)
    infer_range(clip, out, bundle.ranges[1], bundle.key)
    bundle.close()  # the batch stopped
    with pytest.raises(InputError, match="is not ready for frames 0 to 3"):
        infer_range(clip, out, ClipRange(0, 4, 0), bundle.key)
    with folder_lock(tmp_path / "whole"), pytest.raises(InputError, match="another relight is making"):
        infer_clip(clip, tmp_path / "whole")
    record = infer_clip(clip, out)
    assert record["complete"] and record["frames"] == 10 and record["states"]["person"] == 10 and record["shots"] == 1
    assert record["frames_kept_from_earlier_run"] == 4
    assert set(record["pan_offsets"]) == {"4"}
    whole, split = load_clip_bundle(tmp_path / "whole"), load_clip_bundle(out)
    for a, b in zip(whole.frames, split.frames, strict=True):
        assert a.shot == b.shot and a.state == b.state and b.pan_from is None
        assert np.abs(np.subtract(a.pan, b.pan)).max() < 1.0, (a.index, a.pan, b.pan)
        lights = [js.loads((x.scene_path(a.index) / "lights.json").read_text()) for x in (whole, split)]
        assert lights[0] == lights[1]
        sa, sb = load_scene(whole.scene_path(a.index)), load_scene(split.scene_path(a.index))
        if sa.mask.shape == sb.mask.shape:
            assert np.abs(sa.normal - sb.normal)[sa.mask & sb.mask].mean() < 0.01, a.index
    assert js.loads((out / "frames/000007.json").read_text())["pan_from"] == 4


def test_a_warning_every_frame_gives_is_shown_once_and_counted():
    """A clip's frames warn as photos do; a long clip printed a line a frame: now the first, then the count."""
    import warnings

    from viewer.photo.frame_writes import FrameWarnings

    shown = FrameWarnings("walk.mp4")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for t in (0.5, 1.0, 1.5):
            with pytest.raises(NoPersonError) if t == 1.5 else contextlib.nullcontext(), shown.frame(f"walk.mp4 at {t} s"):
                warnings.warn(f"walk.mp4 at {t} s: the person is sideways", stacklevel=1)
                if t == 1.5:
                    raise NoPersonError("walk.mp4", "no person")  # (its warnings before it still count)
        shown.close()
    assert [str(w.message) for w in caught] == ["walk.mp4 at 0.5 s: the person is sideways",
                                                 "walk.mp4: 2 more frames: the person is sideways"]


def test_shots_cut_where_the_picture_changes():
    """A person moving and the camera panning stay one shot; another place is a new one; a lost
    frame stays in the shot before it."""
    from viewer.photo.shots import ShotCuts

    people = person_frames(3)
    rng = np.random.default_rng(0)
    elsewhere = np.clip(rng.normal((40, 120, 60), 25, (480, 320, 3)), 0, 255).astype(np.uint8)  # a green field
    cuts = ShotCuts()
    assert [cuts.shot_of(f) for f in (people[0], people[1], None, people[2], elsewhere, elsewhere[:, ::-1])] == [0, 0, 0, 0, 1, 1]
    brighter = np.clip(people[2].astype(np.int32) + 25, 0, 255).astype(np.uint8)  # a light comes on: not a cut
    assert ShotCuts().shot_of(people[2]) == 0
    cuts = ShotCuts()
    assert [cuts.shot_of(f) for f in (people[2], brighter)] == [0, 0]


def test_steady_maps_follow_the_flow_and_calm_the_noise():
    """Frames of a scene moving 3 pixels a frame, each with its own noise on the normals: steadied,
    the noise falls by more than a third and the maps stay where the person is (no smear: the
    steadied normals are nearer the true moved ones than the raw); a new shot starts afresh."""
    from dataclasses import replace

    from viewer.photo.steady import SteadyMaps
    from viewer.resources import sample_scene_dir
    from viewer.scene.bundle import load_scene

    base = load_scene(sample_scene_dir())
    rng = np.random.default_rng(1)
    texture = (rng.random((base.height, base.width, 3)) * 255).astype(np.uint8)
    import cv2

    texture = cv2.GaussianBlur(texture, (0, 0), 2.0)
    texture = np.clip((texture.astype(np.float32) - texture.mean()) * 6 + 128, 0, 255).astype(np.uint8)

    def frame(t: int):
        shift = lambda a: np.roll(a, 3 * t, axis=1)  # noqa: E731
        normal = shift(base.normal) + rng.normal(0, 0.08, base.normal.shape).astype(np.float32)
        normal = np.where(shift(base.mask)[..., None], normal / np.linalg.norm(normal, axis=2, keepdims=True), shift(base.normal))
        scene = replace(base, albedo=shift(base.albedo), specular=shift(base.specular), roughness=shift(base.roughness),
                        depth=shift(base.depth), mask=shift(base.mask), normal=normal.astype(np.float32)).validate()
        photo = np.where(shift(base.mask)[..., None], (shift(base.albedo) * 255).astype(np.uint8), shift(texture))
        return scene, np.ascontiguousarray(photo), replace(base, normal=shift(base.normal), mask=shift(base.mask))

    steady = SteadyMaps()
    raw_err, steady_err, shares = [], [], []
    for t in range(8):
        scene, photo, truth = frame(t)
        out, share = steady.steady(scene, photo, shot=0)
        shares.append(share)
        inner = cv2.erode(truth.mask.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
        inner[:, :24 + 3 * t] = False  # the wrapped columns
        raw_err.append(float(np.linalg.norm(scene.normal - truth.normal, axis=2)[inner].mean()))
        steady_err.append(float(np.linalg.norm(out.normal - truth.normal, axis=2)[inner].mean()))
    assert shares[0] == 0.0 and min(shares[1:]) > 0.8
    assert np.mean(steady_err[3:]) < 0.65 * np.mean(raw_err[3:])
    # the work frame's size follows the person's (a few pixels from frame to frame): still carried
    from viewer.scene.resampling import resample_scene

    scene, photo, _ = frame(8)
    _, share = steady.steady(resample_scene(scene, 500), photo, shot=0)
    assert share > 0.8
    _, share = steady.steady(*frame(9)[:2], shot=1)  # a cut
    assert share == 0.0


def test_grain_does_not_speckle_the_steadied_maps():
    """A grainy frame (single pixels 60 grey levels off: a noisy render's sparkles, high ISO) fails the
    flow's photo check at those pixels alone: the maps are blended there as around them, so the depth
    of a person who moved 5 cm back has no pixel-scale steps (each a shadow when relit: a relit
    synthetic clip came out speckled with black dots)."""
    from dataclasses import replace

    import cv2

    from viewer.photo.steady import KEEP, SteadyMaps
    from viewer.resources import sample_scene_dir
    from viewer.scene.bundle import load_scene

    base = load_scene(sample_scene_dir())
    h, w = base.mask.shape
    rng = np.random.default_rng(5)
    photo = np.clip(rng.normal(128, 30, (h, w, 3)), 0, 255).astype(np.uint8)
    photo = cv2.GaussianBlur(photo, (0, 0), 3)  # texture the flow can follow
    grainy = photo.copy()
    sparkles = rng.uniform(size=(h, w)) < 0.03
    grainy[sparkles] = np.clip(grainy[sparkles].astype(int) + 60, 0, 255).astype(np.uint8)
    steady = SteadyMaps()
    steady.steady(base, photo, shot=0)
    out, carried = steady.steady(replace(base, depth=np.where(base.mask, base.depth + 0.05, base.depth).astype(np.float32)), grainy, shot=0)
    inside = cv2.erode(base.mask.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
    moved = (out.depth - base.depth)[inside]
    assert carried > 0.8
    assert np.median(moved) == pytest.approx((1 - KEEP) * 0.05, abs=0.003)  # blended, sparkles or not
    steps = np.abs(out.depth - cv2.medianBlur(out.depth.astype(np.float32), 3))[inside]
    assert (steps > 0.01).mean() < 0.001  # no pixel-scale steps at the sparkles (blended only between them: 2.9 %)


def test_the_steadied_matte_neither_adds_coverage_nor_cuts_holes():
    """A still person before a plain wall (the flow holds everywhere): frame 0's matte also covers a
    block of the wall, frame 1's covers a hand frame 0 did not have. Steadied, frame 1's matte is 0
    wherever its own is (no block of the old background carried in), 1 over the new hand (no hole),
    stays under one half where its own calls it background (a faint 0.05 of its own where frame 0 had
    1 came out 0.62: the person's there) and the soft edge values it shares with frame 0 are blended."""
    from dataclasses import replace

    from viewer.photo.steady import KEEP, OWN_BACKGROUND, SteadyMaps
    from viewer.resources import sample_scene_dir
    from viewer.scene.bundle import FrameLayer, load_scene

    base = load_scene(sample_scene_dir())
    h, w = base.mask.shape
    photo = np.full((h, w, 3), 128, np.uint8)
    photo[base.mask] = (base.albedo[base.mask] * 255).astype(np.uint8)
    edge = base.mask.astype(np.float32)
    edge[base.mask & ~np.roll(base.mask, 2, axis=1)] = 0.5  # a soft column at the person's edge

    def scene_with(alpha):
        layer = FrameLayer(albedo=base.albedo, alpha=alpha.astype(np.float32), photo=photo.astype(np.float32) / 255)
        return replace(base, frame=layer)

    before = edge.copy()
    before[10:40, 10:40] = 1.0  # the wall block
    before[10:40, w - 40:w - 10] = 1.0  # another, which frame 1's soft edge touches faintly
    now = edge.copy()
    now[h - 40:h - 10, w - 40:w - 10] = 1.0  # the new hand
    now[10:40, w - 40:w - 10] = 0.05
    now[edge == 0.5] = 0.3
    steady = SteadyMaps()
    steady.steady(scene_with(before), photo, shot=0)
    out, _ = steady.steady(scene_with(now), photo, shot=0)
    alpha = out.frame.alpha
    assert alpha[now == 0].max() == 0.0
    assert alpha[h - 40:h - 10, w - 40:w - 10].min() == 1.0
    assert alpha[now < OWN_BACKGROUND].max() <= 0.5
    soft = (edge == 0.5) & (now == 0.3)
    assert np.allclose(np.median(alpha[soft]), (1 - KEEP) * 0.3 + KEEP * 0.5, atol=0.02)


def test_the_camera_turn_is_read_from_the_old_background(ctx, clip_bundle):
    """A background sliding 0.4 px a frame behind a person who moves on their own: the camera's
    motion adds up to 0.4 px a frame (sub-pixel), a cut starts again; and the look turned by
    ``turned`` moves the new background by that many pixels (measured on the engine's picture)."""
    import cv2

    from viewer.gl import Engine, EngineOptions
    from viewer.lighting.envmap import load_envmap
    from viewer.output.render import render_look
    from viewer.photo.camera_motion import CameraMotion, turned
    from viewer.photo.flow import dis_flow
    from viewer.scene.area_lights import load_lights
    from viewer.scene.bundle import load_scene
    from viewer.scene.look import Look

    rng = np.random.default_rng(5)
    texture = cv2.GaussianBlur((rng.random((300, 420, 3)) * 255).astype(np.uint8), (0, 0), 3.0)
    motion = CameraMotion()
    shifts = []
    for t in range(6):
        m = np.float32([[1, 0, -0.4 * t], [0, 1, 0.2 * t]])
        frame = cv2.warpAffine(texture, m, (420, 300), borderMode=cv2.BORDER_REFLECT)
        alpha = np.zeros((300, 420), np.float32)
        x = 150 + 9 * t  # the person walks right on their own
        alpha[60:260, x:x + 60] = 1.0
        frame[60:260, x:x + 60] = (200, 120, 90)
        shifts.append(motion.shift_of(frame, alpha, shot=0))
    assert abs(shifts[5][0] + 2.0) < 0.15 and abs(shifts[5][1] - 1.0) < 0.1, shifts
    assert motion.shift_of(texture, None, shot=1) == (0.0, 0.0)

    scene = load_scene(clip_bundle[0] / "frames" / "000000")
    env = load_envmap(asset_dir() / "envmaps/immenstadter_horn_256.hdr")
    lights = load_lights(asset_dir() / "envmaps/immenstadter_horn_256.lights.json")
    engine = Engine(ctx, scene, EngineOptions())
    try:
        focal = scene.camera.focal_px * scene.frame.width / scene.width
        pictures = []
        for shift in ((0.0, 0.0), (-6.0, 4.0)):
            yaw, tilt = turned(shift, focal)
            render_look(engine, scene, lights, Look(yaw=30.0 + yaw, tilt=tilt, exposure=0.0, backdrop_blur=0.0), env.pixels)
            pictures.append(cv2.cvtColor(engine.output.read_background_display(), cv2.COLOR_RGB2GRAY))
    finally:
        engine.release()
    flow = dis_flow().calc(pictures[1], pictures[0], None)  # where each pixel of the turned view came from
    moved = -np.median(flow.reshape(-1, 2), axis=0)
    assert np.allclose(moved, (-6.0, 4.0), atol=0.8), moved


def test_the_warping_error_sees_flicker_and_not_motion():
    """The bench's warping error (Lai et al. 2018): an output that moves as the input does scores as
    the input; one that flickers, or stands still while the input pans, scores worse."""
    import cv2

    from viewer.lab.bench.video import WarpingError

    rng = np.random.default_rng(2)
    texture = cv2.GaussianBlur((rng.random((200, 300, 3)) * 255).astype(np.uint8), (0, 0), 3.0)
    meter = WarpingError(["input", "same", "flicker", "still"])
    alpha = np.zeros((120, 160), np.float32)
    alpha[30:90, 50:110] = 1.0
    for t in range(6):
        frame = np.ascontiguousarray(texture[20:140, 10 + 2 * t:170 + 2 * t])
        flicker = np.clip(frame.astype(np.int32) + (12 if t % 2 else -12), 0, 255).astype(np.uint8)
        meter.add(frame, {"input": frame, "same": frame, "flicker": flicker, "still": texture[20:140, 10:170]}, alpha)
    e = meter.result()
    assert e["same"] == e["input"] and e["input"] < 1e-3
    assert e["flicker"] > 20 * e["input"] and e["still"] > 20 * e["input"]
    assert meter.result("person")["flicker"] > 20 * meter.result("person")["input"]
    similar = meter.result(ssim=True)
    assert similar["same"] == similar["input"] > 0.99 and similar["still"] < 0.95 and similar["flicker"] < similar["input"]


def test_pieces_of_matte_that_come_and_go_are_counted():
    """A matte that moves with the scene has no piece coming or going (its outline a pixel off is no
    piece either); a blob of the old background kept in one frame only counts where it comes and
    where it goes."""
    import cv2

    from viewer.lab.bench.video import MattePieces, WarpingError

    rng = np.random.default_rng(4)
    texture = cv2.GaussianBlur((rng.random((200, 300, 3)) * 255).astype(np.uint8), (0, 0), 3.0)
    steady, popping, flows = MattePieces(), MattePieces(), WarpingError(["input"])
    for t in range(6):
        frame = np.ascontiguousarray(texture[20:140, 10 + 2 * t:170 + 2 * t])
        flow = flows.add(frame, {"input": frame})
        alpha = np.zeros((120, 160), np.float32)
        alpha[30:90, 50 - 2 * t:110 - 2 * t + (t % 2)] = 1.0  # the person, moving with the scene (a pixel of jitter)
        steady.add(t, flow, alpha)
        kept = alpha.copy()
        if t == 3:
            kept[10:28, 120:140] = 1.0  # a piece of background kept in frame 3 alone
        popping.add(t, flow, kept)
    assert steady.result() == {"pieces": 0, "pairs": 5, "frames_with_pieces": []}
    assert popping.result() == {"pieces": 2, "pairs": 5, "frames_with_pieces": [3, 4]}


def test_a_batch_relights_clips_beside_photos(tmp_path):
    """A folder with a clip and a photo: the clip relit into CLIP/LOOK.mp4 (its frames and sound) with
    its middle frame as CLIP/LOOK.png (in the contact sheet), the photo as ever; run again, nothing
    is done; a foreign file where the clip's audio would go beside it fails that item alone."""
    import shutil as sh

    from test_batch import batch, events

    folder = tmp_path / "in"
    folder.mkdir()
    write_clip(folder / "walk.mp4", person_frames(3))
    sh.copy(asset_dir() / "photos/underpass.jpg", folder / "underpass.jpg")
    out = tmp_path / "out"
    env = asset_dir() / "envmaps/immenstadter_horn_256.hdr"
    res = batch(tmp_path, folder, "--env", env, "-o", out, "--workers", "1")
    assert res.returncode == 0, res.stderr
    assert "2 done, 0 failed" in res.stdout
    mp4, = (out / "walk").glob("*.mp4")
    frames, times, audio = decoded(mp4)
    assert len(frames) == 3 and audio and frames[0].shape[0] == 256
    poster = read_png(mp4.with_suffix(".png"))
    h, w = frames[1].shape[:2]  # (H.264's even width)
    assert poster.shape[0] == h and poster.shape[1] - w in (0, 1) and np.abs(poster[:, :w] * 255 - frames[1]).mean() < 4
    assert sorted(p.name for p in out.glob("underpass/*")) == [mp4.stem + ".exr", mp4.stem + ".png"]
    done = {e["item"]: e for e in events(out) if e["event"] == "done"}
    assert set(done["walk/" + mp4.stem]["outputs"]) == {f"walk/{mp4.stem}.png", f"walk/{mp4.stem}.mp4"}
    assert (out / "contact-sheet.png").is_file()
    res = batch(tmp_path, folder, "--env", env, "-o", out, "--workers", "1")
    assert res.returncode == 0 and "nothing to do, 2 items already done" in res.stdout, res.stdout + res.stderr
    mine = out / "walk" / f"{mp4.stem}_y90.audio.mp4"
    mine.write_text("mine")
    res = batch(tmp_path, folder, "--env", env, "-o", out, "--workers", "1", "--yaw", "90")
    assert res.returncode == 1 and "1 done, 1 failed" in res.stdout and "audio.mp4: is not a file relight wrote" in res.stderr
    assert mine.read_text() == "mine"
    from viewer.files.imageio import write_png

    write_png(tmp_path / "square.png", np.full((200, 300, 3), 0.5, np.float32))  # a plate look: the clip on it too
    res = batch(tmp_path, folder, "--plate", tmp_path / "square.png", "--height", "0.6", "--horizon", "0.4", "-o", out,
                "--workers", "1")
    assert res.returncode == 0 and "2 done, 0 failed" in res.stdout, res.stdout + res.stderr
    frames, _, _ = decoded(out / "walk" / "on_square.mp4")
    # the person on the grey plate, the plate no larger than the batch's --max-size (256)
    assert len(frames) == 3 and frames[0].shape[:2] == (170, 256) and frames[0].std() > 5


def test_a_clip_dataset_measured_against_its_truth(tmp_path):
    """``relight dataset make --split clip``: a person turning, filmed under one shared map (input MP4 and
    EXRs) with the truth under another; a frame lost is made again alone, the same; ``relight bench
    video --truth`` infers the clip both ways and gives each frame's relit RMSE against the truth."""
    from test_cli import run_cli

    from viewer.files.imageio import read_exr
    from viewer.lab.bench.clip_truth import relit_rmse

    maps = tmp_path / "maps"
    maps.mkdir()
    for name in ("potsdamer_platz_1k.hdr", "rooitou_park_1k.hdr"):
        shutil.copy(SHARED_DATA / "hdri" / name, maps / name)
    data = tmp_path / "clips"
    args = ("dataset", "make", "--out", str(data), "--count", "1", "--res", "192", "--spp", "4", "--split", "clip",
            "--frames", "3", "--maps", str(maps))
    res = run_cli(*args)
    assert res.returncode == 0, res.stderr
    clip = data / "clips" / "000000"
    record = json.loads((clip / "clip.json").read_text())
    assert record["frames"] == 3 and record["input"]["map"] != record["truth"]["map"]
    assert record["turns"][0] != record["turns"][-1]  # the person turns
    truth = read_exr(clip / "truth" / "000001.exr")
    assert truth.shape == (192, 192, 4) and 0.05 < (truth[..., 3] > 0.5).mean() < 0.5 and np.isfinite(truth).all()
    assert len(decoded(clip / "input.mp4")[0]) == 3
    (clip / "truth" / "000001.exr").unlink()
    (clip / "clip.json").unlink()
    assert run_cli(*args).returncode == 0
    np.testing.assert_array_equal(read_exr(clip / "truth" / "000001.exr"), truth)  # made again, the same
    res = run_cli(*args[:-4], "--frames", "4", "--maps", str(maps))  # other settings: refused, nothing mixed
    assert res.returncode == 2 and "made with other settings" in res.stderr and "Traceback" not in res.stderr
    out = tmp_path / "bench" / "truth.json"
    res = run_cli("bench", "video", "--truth", str(data), "-o", str(out))
    assert res.returncode == 0, res.stderr
    figures = json.loads(out.read_text())["clips"][0]
    for mode in ("on", "off"):
        rmse = figures["modes"][mode]["rmse"]
        assert len(rmse["per_frame"]) == 3 and 0.0 < rmse["mean"] < 1.0, (mode, rmse)
    assert figures["warping_error"]["input"] > 0
    # the measure: one scale for the clip, relative to the truth
    t = [np.dstack([np.full((4, 4, 3), v, np.float32), np.ones((4, 4), np.float32)]) for v in (1.0, 2.0)]
    assert relit_rmse([3 * x for x in t], t)["mean"] == pytest.approx(0.0, abs=1e-9)
    wavering = relit_rmse([t[0] * 1.5, t[1]], t)  # a brightness that wavers counts
    assert wavering["mean"] > 0.05


def test_a_clip_recording_keeps_its_frames_when_the_audio_cannot_join(clip_bundle, ctx, tmp_path, monkeypatch):
    """The window's recording of a clip (R): its frames at the source's times with the audio joined; a
    join that fails keeps the frames (a video without audio, said); a recording of no frame leaves no file."""
    from viewer.app.recording import ClipRecording
    from viewer.app.timeline import ClipTimeline
    from viewer.output import clip_render
    from viewer.scene.clip_bundle import load_clip_bundle

    timeline = ClipTimeline(ctx, load_clip_bundle(clip_bundle[0]))
    try:
        frames = [np.full((48, 64, 3), 40 * k, np.uint8) for k in range(len(timeline.times))]
        rec = ClipRecording(tmp_path / "a.mp4", (64, 48), timeline)
        for f in frames:
            rec.add(f)
        assert rec.close() == tmp_path / "a.mp4" and rec.note is None
        got, times, audio = decoded(tmp_path / "a.mp4")
        assert len(got) == len(frames) and times == pytest.approx(timeline.times) and audio
        monkeypatch.setattr(clip_render, "join_relit", lambda *a, **k: (_ for _ in ()).throw(OSError("no room")))
        rec = ClipRecording(tmp_path / "b.mp4", (64, 48), timeline)
        for f in frames[:3]:
            rec.add(f)
        assert rec.close() == tmp_path / "b.mp4" and "without its audio (no room)" in rec.note
        got, times, audio = decoded(tmp_path / "b.mp4")
        assert len(got) == 3 and not audio
        rec = ClipRecording(tmp_path / "c.mp4", (64, 48), timeline)
        with pytest.raises(RuntimeError, match="no frame"):
            rec.close()
        assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mp4", "b.mp4"]  # nothing else left behind
    finally:
        timeline.release()


def test_a_bystander_who_comes_nearer_stays_out_of_the_matte(tmp_path):
    """The person is followed through the clip: a bystander who steps in, nearer the camera and
    larger, is left out of every frame's matte (a photo would relight the largest)."""
    import cv2

    from viewer.photo.clip_inference import infer_clip
    from viewer.photo.frames import read_photo
    from viewer.resize import resize
    from viewer.scene.bundle import load_scene
    from viewer.scene.clip_bundle import load_clip_bundle

    photos = SHARED_DATA / "photos"
    near = read_photo(photos / "unsplash-1535323700481.jpg", [])  # the bystander, large
    gone = (read_png(photos / "unsplash-1535323700481.mask.png")[..., 0] > 0.5).astype(np.uint8)
    empty = cv2.inpaint(near, cv2.dilate(gone, np.ones((25, 25), np.uint8)), 5, cv2.INPAINT_TELEA)  # the place, no one in it
    person = read_photo(photos / "unsplash-1507274733827.jpg", [])
    height = 300
    left = [resize(x, (x.shape[1] * height // x.shape[0], height)) for x in (empty, near)]
    right = resize(person, (person.shape[1] * 180 // person.shape[0], 180))
    frames = []
    for side in (left[0], left[1], left[1]):  # the bystander steps in at frame 1
        frame = np.zeros((height, side.shape[1] + right.shape[1], 3), np.uint8)
        frame[:, :side.shape[1]] = side
        frame[height - 180:, side.shape[1]:] = right
        frame[:height - 180, side.shape[1]:] = right[:1].mean(axis=(0, 1)).astype(np.uint8)
        frames.append(frame)
    split = left[0].shape[1]
    clip = write_clip(tmp_path / "bystander.mp4", frames, audio=None)
    record = infer_clip(clip, tmp_path / "bundle")
    bundle = load_clip_bundle(tmp_path / "bundle")
    assert record["shots"] == 1 and [e.state for e in bundle.frames] == ["person"] * 3
    for entry in bundle.frames:
        alpha = load_scene(bundle.scene_path(entry.index)).frame.alpha
        assert alpha[:, split:].sum() > 0.95 * alpha.sum() and alpha[:, split:].sum() > 1000, entry.index


def test_the_person_chosen_is_followed_and_their_absence_said_once(tmp_path, capsys):
    """`relight infer CLIP --person X,Y` relights the person pointed at (not the larger one beside
    them) in every frame they are in, says whom it chose with a preview, and a frame they are out of
    shows no one, said once with its frame; another person is never relit in their place."""
    from test_segmentation import two_people

    from viewer.cli.main import main
    from viewer.files.imageio import read_png
    from viewer.resize import resize
    from viewer.scene.bundle import load_scene
    from viewer.scene.clip_bundle import load_clip_bundle

    two, split = two_people()
    scale = 600 / two.shape[0]
    frame = resize(two, (int(two.shape[1] * scale) // 2 * 2, 600))
    split = int(split * scale)
    alone = frame.copy()
    alone[:, split:] = frame[:20, split:].mean(axis=(0, 1)).astype(np.uint8)  # the right-hand person gone
    clip = write_clip(tmp_path / "two.mp4", [frame, frame, alone, frame], audio=None)
    x = (split + 0.5 * (frame.shape[1] - split)) / frame.shape[1]
    assert main(["infer", str(clip), "-o", str(tmp_path / "bundle"), "--person", f"{x:.3f},0.8"]) == 0
    said = capsys.readouterr().out
    assert "relighting the person at" in said and "under --person" in said and "1 other there left out" in said
    assert "no one relit in frame 2 (0.20-0.20 s): the person followed is not in the picture (1 other in it)" in said
    bundle = load_clip_bundle(tmp_path / "bundle")
    assert [e.state for e in bundle.frames] == ["person", "person", "no person", "person"]
    for index in (0, 1, 3):
        a = load_scene(bundle.scene_path(index)).frame.alpha
        assert a[:, split:].sum() > 0.95 * a.sum() and a[:, split:].sum() > 1000, index
    preview = read_png(tmp_path / "bundle" / "person.png")
    assert preview.shape[2] == 3 and preview[..., 1].max() > 0.9  # the chosen one outlined in green
    with pytest.raises(SystemExit):
        main(["infer", str(clip), "-o", str(tmp_path / "b2"), "--person", "1.5,0.2"])
    assert "fractions of the frame" in capsys.readouterr().err
    photo = SHARED_DATA / "photos" / "unsplash-1507274733827.jpg"
    assert main(["infer", str(photo), "-o", str(tmp_path / "b3"), "--people", "all"]) == 2
    assert "--people is for a clip: this is not one" in capsys.readouterr().err
    assert not (tmp_path / "b3").exists()


def test_the_new_ground_is_where_the_clips_camera_sees_its_own_and_as_high(tmp_path):
    """A clip filmed by a camera looking 10 degrees down on a city square: the camera's pitch is read
    from the square's converging verticals (the person's own edges left out), and the map behind the
    relit person is tilted by as much, so its horizon lies where the square's did (within 3 % of the
    frame's height), not across the middle; the camera's height above the square is read from the person
    standing on it, as the camera the map is seen through sees them."""
    from viewer.files.imageio import linear_to_srgb
    from viewer.lighting.envmap import LUMINANCE, load_envmap
    from viewer.output.clip_frames import ClipFrames
    from viewer.photo.clip_cache import ClipRequest
    from viewer.photo.clip_inference import infer_clip
    from viewer.photo.frames import read_photo
    from viewer.plate.loader import DEFAULT_FOCAL_35
    from viewer.resize import resize
    from viewer.scene.area_lights import rotation_matrix
    from viewer.scene.camera import Camera
    from viewer.scene.clip_bundle import load_clip_bundle

    square = SHARED_DATA / "hdri" / "potsdamer_platz_1k.hdr"
    env = load_envmap(square)
    camera = Camera(640, 426, focal_mm=DEFAULT_FOCAL_35, sensor_mm=36.0)  # the lens a clip without EXIF is taken to have
    linear = env.seen_through(camera, 240.0, 10.0)
    background = (np.clip(linear_to_srgb(linear * 0.18 / np.median(linear @ LUMINANCE)), 0, 1) * 255 + 0.5).astype(np.uint8)
    seen = camera.view_directions() @ rotation_matrix(240.0, 10.0)
    truth = np.argmin(np.abs(seen[:, 320, 1])) / 426.0  # where the square's horizon crosses the middle column
    assert truth < 0.3  # looking down: the horizon high in the frame
    photo = read_photo(SHARED_DATA / "photos" / "unsplash-1507274733827.jpg", [])
    mask = read_png(SHARED_DATA / "photos" / "unsplash-1507274733827.mask.png")
    mask = mask[..., 0] if mask.ndim == 3 else mask
    rows, cols = np.flatnonzero(mask.max(axis=1) > 0.5), np.flatnonzero(mask.max(axis=0) > 0.5)
    photo, mask = photo[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1], mask[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
    # a person of 1.7 m standing on the square 3 m below the camera, their feet at row 400: their head where
    # the camera sees it (the rays down the middle column, 10 degrees down and the lens's angle)
    focal, feet, up = camera.focal_px, 400, 3.0

    def row(down: float) -> float:  # the row whose ray is ``down`` (a tangent) below the horizon
        return 213.0 + focal * np.tan(np.arctan(down) - np.radians(10.0))

    down = np.tan(np.radians(10.0) + np.arctan((feet - 213.0) / focal))
    tall = int(round(feet - row(down * (up - 1.7) / up)))
    size = (photo.shape[1] * tall // photo.shape[0], tall)
    person, alpha = resize(photo, size), resize(mask.astype(np.float32), size)[..., None]
    x0 = 320 - size[0] // 2
    frame = background.copy()
    frame[feet - tall:feet, x0:x0 + size[0]] = (alpha * person + (1 - alpha) * frame[feet - tall:feet, x0:x0 + size[0]]).astype(np.uint8)
    clip = write_clip(tmp_path / "square.mp4", [frame, frame], audio=None)
    infer_clip(clip, tmp_path / "bundle")
    frames = ClipFrames(load_clip_bundle(tmp_path / "bundle"))
    pitch, how = frames.pitch(0)
    assert "from" in how and "down" in how, how
    yaw, tilt = frames.camera_turn(1, 1)
    assert tilt == pytest.approx(pitch, abs=0.5)  # the still camera turned no further
    # the map the relit frame shows behind, seen through the bundle's camera tilted so: its horizon where the square's was
    back = frames.background_camera(0)
    directions = Camera(640, 426, focal_mm=back.focal_mm, sensor_mm=back.sensor_mm).view_directions() @ rotation_matrix(0.0, tilt)
    assert np.argmin(np.abs(directions[:, 320, 1])) / 426.0 == pytest.approx(truth, abs=0.03)
    # the camera's height read from the person standing there, through the camera the map is seen through
    # (the shot's lens, wider than the clip's: the map's ground drawn at the feet at the size it has there):
    # its ray through their feet meets the ground where its ray through the top of their head passes 1.7 m up
    height = frames.camera_height(1)
    tilted = Camera(640, 426, focal_mm=back.focal_mm, sensor_mm=back.sensor_mm).view_directions() @ rotation_matrix(0.0, tilt)
    down = -tilted[:, 320, 1] / np.hypot(tilted[:, 320, 0], tilted[:, 320, 2])
    distance = height / down[feet - 1]
    assert height - distance * down[feet - tall] == pytest.approx(1.7, rel=0.05), (height, tall)
    assert 1.7 < height < up  # above the person's head (it is below the horizon), and the lens wider than the clip's
    # standing on the new ground: the map behind their feet is the map's ground in every frame (relight bench video)
    from viewer.lab.bench.video import feet_over_the_sky

    assert feet_over_the_sky(load_clip_bundle(tmp_path / "bundle"))["over_the_sky"] == 0
    # seen frame by frame (a level camera) with their feet above the middle of the frame, they float over the sky
    high = background.copy()
    top = 200 - tall
    high[top:200, x0:x0 + size[0]] = (alpha * person + (1 - alpha) * high[top:200, x0:x0 + size[0]]).astype(np.uint8)
    infer_clip(write_clip(tmp_path / "high.mp4", [high, high], audio=None), tmp_path / "high", request=ClipRequest(temporal="off"))
    floating = feet_over_the_sky(load_clip_bundle(tmp_path / "high"))
    assert floating["frames_with_feet"] == floating["over_the_sky"] == 2, floating


def test_the_windows_relit_frames_are_what_it_shows_live(clip_bundle, ctx):
    """``relight view CLIP`` plays a clip from the pictures it relit ahead (viewer/app/relit_frames.py):
    each is the picture the window shows of that frame live (the person's, the lost frame's, the empty
    frame's background alone), and a change of the lighting drops them."""
    from viewer.app.relit_frames import RelitFrames
    from viewer.app.session import Session
    from viewer.app.timeline import ClipTimeline
    from viewer.lighting.envmap import load_envmap
    from viewer.scene.area_lights import load_lights
    from viewer.scene.clip_bundle import load_clip_bundle
    from viewer.scene.look import Look

    timeline = ClipTimeline(ctx, load_clip_bundle(clip_bundle[0]))
    first = timeline.frames.shown(0)[1]
    env = load_envmap(asset_dir() / "envmaps/immenstadter_horn_256.hdr")
    session = Session(ctx, timeline.frames.scene(first), load_lights(asset_dir() / "envmaps/immenstadter_horn_256.lights.json"),
                      env.pixels, look=Look(yaw=150.0, exposure=0.5), background_camera=timeline.frames.background_camera(first))
    timeline.began(session)
    relit = RelitFrames(ctx, timeline)
    try:
        relit.follow(session)
        for _ in range(2000):
            if not relit.prepare(session, 0.05) and relit.count < timeline.count:
                time.sleep(0.01)  # a scene being read
            if relit.count == timeline.count:
                break
        assert relit.count == timeline.count == 5 and relit.error == ""
        for k in range(timeline.count):
            timeline.seek(k)
            timeline.advance(session, wait=True)
            live = timeline.picture(session.render()).astype(np.int16)
            assert np.abs(relit.pictures[k] - live).max() <= 1, k
        assert np.abs(relit.pictures[2].astype(np.int16) - relit.pictures[0]).mean() > 5.0  # (no one in frame 2)
        session.update(yaw=10.0)
        relit.follow(session)
        assert relit.count == 0 and not relit.ready(0)  # another lighting: relit again
    finally:
        relit.release()
        timeline.release()
        session.release()
