"""Issue 62: one writer per output, a cache that never serves a damaged or stale clip, records and frames trusted
only when they check out, sizes and shapes checked before work."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from viewer.errors import InputError
from viewer.files.output_lock import ExclusiveLock, create_partial, lock_path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def test_one_writer_holds_an_output_and_a_dead_ones_partial_is_taken_up(tmp_path):
    out = tmp_path / "new" / "out.mp4"
    with ExclusiveLock(out):
        assert lock_path(out).is_file() and json.loads(lock_path(out).read_text())["process"] == os.getpid()
        # another process asks for it: refused at once, in one line naming this one
        code = ("import sys; from viewer.files.output_lock import ExclusiveLock\n"
                f"with ExclusiveLock({str(out)!r}): pass")
        res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
        assert res.returncode != 0 and f"is being written by another relight (process {os.getpid()}, since" in res.stderr
        partial = out.with_name("out.partial.mp4")
        create_partial(partial, out)  # a join's, made and recorded
        with pytest.raises(FileExistsError):
            create_partial(partial, out)  # exclusive
        assert sorted(p.name for p in out.parent.iterdir()) == [lock_path(out).name, "out.partial.mp4"]
    assert not lock_path(out).exists() and partial.exists()  # released: the lock gone, the partial (recorded) not touched

    # a run killed outright leaves its lock (flock dropped by the kernel) and its claimed partial: the next takes both
    killer = ("import os, sys; from pathlib import Path; from viewer.files.output_lock import ExclusiveLock, create_partial\n"
              f"out = Path({str(out)!r}); lock = ExclusiveLock(out).__enter__()\n"
              "partial = out.with_name('out.partial.mp4'); partial.unlink(); create_partial(partial, out)\n"
              "partial.write_bytes(b'\\0\\0\\0\\x18ftypisom' + bytes(36)); (out.parent / f'.out.exr.{os.getpid()}.tmp').write_bytes(b'e')\n"
              "os.kill(os.getpid(), 9)")
    subprocess.run([sys.executable, "-c", killer], cwd=ROOT)
    assert lock_path(out).exists() and partial.exists() and len(list(out.parent.glob(".out.exr.*.tmp"))) == 1
    with ExclusiveLock(out):
        assert not partial.exists()  # this program's, cut short: removed, made again by the run
        assert not list(out.parent.glob(".out.exr.*.tmp"))  # the dead run's temporary file too
    user = out.with_name("out.partial.mp4")
    user.write_bytes(b"the user's")  # never recorded: left as it is (the writer refuses it in one line)
    with ExclusiveLock(out):
        pass
    assert user.read_bytes() == b"the user's"

    # a dead run's record names the user's files: an inode freed and taken by their new file (no MP4), a file
    # elsewhere: neither is touched
    elsewhere = tmp_path / "victim.txt"
    elsewhere.write_text("mine")
    st, su = elsewhere.stat(), user.stat()
    lock_path(out).write_text(json.dumps({"format": "relight-lock", "process": 999999999, "partials": {
        str(elsewhere): [st.st_dev, st.st_ino], str(user): [su.st_dev, su.st_ino]}}))
    with ExclusiveLock(out):
        pass
    assert elsewhere.read_text() == "mine" and user.read_bytes() == b"the user's"

    # a missing folder made for the lock goes again when nothing was written; a link or a stranger's file at the
    # lock's name is refused, kept
    gone = tmp_path / "a" / "b" / "x.png"
    with ExclusiveLock(gone):
        pass
    assert not (tmp_path / "a").exists()
    lock_path(out).symlink_to(tmp_path / "elsewhere")
    with pytest.raises(InputError, match="cannot hold the lock"):
        ExclusiveLock(out).__enter__()
    lock_path(out).unlink()
    lock_path(out).write_text("my notes")
    with pytest.raises(InputError, match="not a lock file relight wrote"):
        ExclusiveLock(out).__enter__()
    assert lock_path(out).read_text() == "my notes"


def test_a_render_holds_every_file_it_writes(tmp_path):
    """Another run's -o that is one of a render's files (its passes sheet, a video's partial) is held too."""
    from viewer.resources import asset_dir, sample_scene_dir

    lights = str(asset_dir() / "envmaps" / "venice_sunset_256.lights.json")
    for held, out, more in (("x_passes.png", "x.png", []), ("v.partial.mp4", "v.mp4", ["--frames", "2"])):
        with ExclusiveLock(tmp_path / held):
            res = subprocess.run([sys.executable, "-m", "viewer.cli.main", "render", str(sample_scene_dir()), lights, "--size", "64",
                                  *more, "-o", str(tmp_path / out)], capture_output=True, text=True, cwd=ROOT)
        assert res.returncode == 2 and f"{held}: is being written by another relight (process {os.getpid()}" in res.stderr
        assert res.stderr.count("\n") == 1 and not (tmp_path / out).exists()


def test_the_cache_place_is_absolute_and_never_the_root(monkeypatch, tmp_path):
    from viewer.lighting.lightfit.cache import bundles_dir, cache_dir

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("RELIGHT_CACHE", ".")
    assert cache_dir() == tmp_path and bundles_dir() == tmp_path.parent / "bundles"
    monkeypatch.setenv("RELIGHT_CACHE", "/")
    with pytest.raises(InputError, match="root"):
        cache_dir()


def _clip(path, frames, sar=None):
    from test_clips import write_clip

    return write_clip(path, frames, audio=None, sar=sar)


def test_non_square_pixels_come_out_as_a_player_shows_them(tmp_path):
    from viewer.files.clip_reader import clip_frames, probe_clip

    stored = np.zeros((96, 64, 3), np.uint8)
    stored[:, 32:] = 200  # the right half bright: still the right half once widened
    clip = _clip(tmp_path / "sar.mp4", [stored] * 3, sar=Fraction(2, 1))
    info = probe_clip(clip)
    assert (info.width, info.height, info.sar) == (128, 96, 2.0)
    frames = [f.rgb for f in clip_frames(clip)]
    assert len(frames) == 3 and frames[0].shape == (96, 128, 3)
    assert frames[0][:, :60].mean() < 20 and frames[0][:, 68:].mean() > 180


def test_clips_too_small_and_scripts_are_one_line_before_any_frame(tmp_path):
    from viewer.files.clip_reader import probe_clip
    from viewer.photo.clip_inference import check_frame_size

    for size in ((2, 2), (16, 1000), (1000, 16)):
        clip = _clip(tmp_path / f"{size[0]}x{size[1]}.mp4", [np.full((size[1], size[0], 3), 90, np.uint8)] * 2)
        with pytest.raises(InputError, match="too small or too thin"):
            check_frame_size(clip, probe_clip(clip), 2048)
    _clip(tmp_path / "real.mp4", [np.full((64, 64, 3), 90, np.uint8)] * 2)
    script = tmp_path / "script.mp4"
    script.write_text("ffconcat version 1.0\nfile real.mp4\n")
    with pytest.raises(InputError, match="names other files"):
        probe_clip(script)


def test_a_clip_changed_while_it_is_inferred_is_not_kept(tmp_path):
    """Its frames may be the damaged file's: no bundle is left to be served as the clip's."""
    from test_clips import person_frames, write_clip

    from viewer.photo.clip_inference import infer_clip
    from viewer.scene.clip_bundle import RECORD

    clip = write_clip(tmp_path / "walk.mp4", person_frames(3, 160, 240), audio=None)

    def touched(done, total, entry):
        if done == 1:
            os.utime(clip)  # written over and put back: its change time moves

    out = tmp_path / "bundle"
    with pytest.raises(InputError, match="changed while it was being inferred"):
        infer_clip(clip, out, progress=touched)
    assert not (out / RECORD).exists() and not (out / "frames").exists()


def test_a_clip_changed_while_its_ranges_are_inferred_is_not_kept(tmp_path):
    """The same on the workers' path (a batch's or --ray's ranges, finished by their driver)."""
    from test_clips import person_frames, write_clip

    from viewer.photo.clip_ranges import infer_range, open_ranges
    from viewer.scene.clip_bundle import RECORD

    clip = write_clip(tmp_path / "walk.mp4", person_frames(4, 160, 240), audio=None)
    bundle = open_ranges(clip, tmp_path / "ranges", 2, overlap=1)
    try:
        results = [infer_range(clip, bundle.path, r, bundle.key) for r in bundle.ranges]
        os.utime(clip)
        with pytest.raises(InputError, match="changed while it was being inferred"):
            bundle.finish(clip, results)
    finally:
        bundle.close()
    assert not (bundle.path / RECORD).exists() and not (bundle.path / "frames").exists()


def test_a_damaged_cached_clip_bundle_is_moved_aside_and_made_again(tmp_path):
    from test_clips import person_frames, write_clip

    from viewer.photo.clip_inference import infer_clip
    from viewer.scene.clip_bundle import load_clip_bundle

    clip = write_clip(tmp_path / "walk.mp4", person_frames(3, 160, 240), audio=None)
    cache = tmp_path / "bundles" / "walk-clip-0123"
    infer_clip(clip, cache, cached=True)
    albedo = cache / "frames" / "000001" / "albedo.exr"
    albedo.write_bytes(albedo.read_bytes()[:100])  # all of it still this program's files: removed, made again
    with pytest.warns(UserWarning, match="did not check out .*: removed, the clip is inferred again"):
        record = infer_clip(clip, cache, cached=True)
    assert record["frames"] == 3 and load_clip_bundle(cache).frames[1].state == "person"
    assert [p.name for p in cache.parent.iterdir()] == [cache.name]
    albedo.write_bytes(albedo.read_bytes()[:100])
    (cache / "mine.txt").write_text("kept")  # a file of the user's in it: the whole entry moved aside, nothing removed
    with pytest.warns(UserWarning, match="did not check out .*moved aside"):
        record = infer_clip(clip, cache, cached=True)
    assert record["frames"] == 3 and load_clip_bundle(cache).frames[1].state == "person"
    aside = [p for p in cache.parent.iterdir() if p.name.startswith(".walk-clip-0123.damaged-")]
    assert len(aside) == 1 and (aside[0] / "mine.txt").read_text() == "kept"  # nothing of it removed
    # given by the user (not the cache's): refused as before, nothing moved
    with pytest.raises(InputError, match="relight did not write"):
        infer_clip(clip, aside[0])


def test_records_and_maps_checked_on_reading(tmp_path):
    from viewer.files.imageio import write_exr
    from viewer.lighting.envmap import load_envmap
    from viewer.scene.clip_bundle import check_record

    good = {"version": 2, "source": {"path": "c.mp4", "sha256": "0" * 64, "width": 64, "height": 48, "fps": 25.0},
            "options": {"start": 0.0, "end": None}, "complete": True, "frames": 3}
    check_record(good, tmp_path / "clip.json")
    for field, value, words in (("frames", "abc", "frames must be"), ("frames", True, "frames must be"),
                                ("first_frame_at", 1e300, "first_frame_at"), ("first_frame_at", float("nan"), "first_frame_at")):
        with pytest.raises(InputError, match=words):
            check_record({**good, field: value}, tmp_path / "clip.json")
    with pytest.raises(InputError, match="source.fps"):
        check_record({**good, "source": {**good["source"], "fps": 0}}, tmp_path / "clip.json")
    with pytest.raises(InputError, match="person.frame"):
        check_record({**good, "person": {"box": [0.1, 0.1, 0.5, 0.8], "frame": 50}}, tmp_path / "clip.json")

    from viewer.scene.clip_bundle import read_frame_entry

    frame = {"index": 2, "seconds": 0.2, "state": "person", "shot": 0, "pan": [1.5, -2.0]}
    path = tmp_path / "000002.json"
    path.write_text(json.dumps(frame))
    assert read_frame_entry(path).pan == (1.5, -2.0)
    for data, words in (([1, 2], "not a clip frame record"), ("hello", "not a clip frame record"),
                        ({**frame, "seconds": True}, "seconds must be"), ({**frame, "index": True}, "index must be"),
                        ({**frame, "pan": [1e300, 0]}, "pan must be"), ({**frame, "pan": [1, 2, 3]}, "pan must be"),
                        ({**frame, "shot": -1}, "shot must be"), ({**frame, "shot": 99}, "shot must be")):
        path.write_text(json.dumps(data))
        with pytest.raises(InputError, match=words) as info:
            read_frame_entry(path)
        assert str(path) in str(info.value)

    ringing = np.ones((32, 64, 3), np.float32)
    ringing[5, 7] = [-0.02, 0.5, 0.5]  # a Lanczos filter's ringing beside a sun
    write_exr(tmp_path / "ringing.exr", ringing)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        env = load_envmap(tmp_path / "ringing.exr")
    assert env.pixels.min() == 0.0 and any("1 pixel(s) had negative values" in str(w.message) for w in said)
    write_exr(tmp_path / "negative.exr", -np.ones((32, 64, 3), np.float32))
    with pytest.raises(InputError, match="negative"):
        load_envmap(tmp_path / "negative.exr")


def test_plates_a_portrait_is_a_plate_and_a_huge_one_is_refused_from_its_header(tmp_path):
    from PIL import Image

    from viewer.lab.bench.robustness.fourth_campaign import _png_header
    from viewer.plate.loader import read_plate

    Image.fromarray(np.full((400, 200, 3), 120, np.uint8)).save(tmp_path / "portrait.png")
    assert read_plate(tmp_path / "portrait.png", []).size == (200, 400)
    Image.fromarray(np.full((200, 400, 3), 120, np.uint8)).save(tmp_path / "pano.png")
    with pytest.raises(InputError, match="panorama"):
        read_plate(tmp_path / "pano.png", [])
    with pytest.raises(InputError, match="14000x14000 pixels: more than the 60 megapixels"):  # its data is cut short:
        read_plate(_png_header(tmp_path / "huge.png", 14000, 14000), [])  # the header's size is what refused it
    frames = [Image.fromarray(np.full((80, 120, 3), v, np.uint8)) for v in (50, 150)]
    frames[0].save(tmp_path / "anim.gif", save_all=True, append_images=frames[1:])
    notes: list = []
    read_plate(tmp_path / "anim.gif", notes)
    assert any("animated (2 frames): its first frame is used" in n for n in notes)
