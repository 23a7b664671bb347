"""The window's background jobs without a window: a photo, a bundle and a map each end with a
result or with one line naming the file (the child process's error, never a traceback)."""

from __future__ import annotations

import shutil
import threading

import numpy as np

from viewer.app.jobs import ChildWorker, LightJob, SceneJob
from viewer.errors import InputError
from viewer.resources import asset_dir, sample_scene_dir


def finished(job, timeout=240.0):
    job._thread.join(timeout)
    assert job.done
    return job


def test_a_bad_photo_and_a_bad_bundle_are_one_line_each(tmp_path):
    bad = tmp_path / "holiday.jpg"
    bad.write_text("not a jpeg")
    job = finished(SceneJob(bad, 256))
    assert job.result is None and job.error.startswith(str(bad)) and "cannot read the photo" in job.error
    assert "\n" not in job.error and "Traceback" not in job.error
    broken = shutil.copytree(sample_scene_dir(), tmp_path / "bundle")
    (broken / "scene.json").write_text("{")
    job = finished(SceneJob(broken, 256))
    assert job.result is None and str(broken / "scene.json") in job.error


def test_a_bundle_opens_at_the_size_asked(tmp_path):
    job = finished(SceneJob(sample_scene_dir(), 256))
    assert job.error is None and job.result.how == "bundle" and max(job.result.scene.output_size) <= 256


def test_a_map_is_fitted_in_the_child_and_cached(tmp_path, monkeypatch):
    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache"))
    new_map = shutil.copyfile(asset_dir() / "envmaps" / "venice_sunset_256.hdr", tmp_path / "sunset.hdr")
    job = finished(LightJob(new_map, 8, "instant"))
    assert job.error is None and job.result.how == "fitted" and len(job.result.lights) == 8
    assert np.all(np.isfinite(job.result.lights.intensity)) and job.result.lights.intensity.sum() > 0
    again = finished(LightJob(new_map, 8, "instant"))
    assert again.result.how == "cached"
    np.testing.assert_array_equal(again.result.lights.direction, job.result.lights.direction)
    broken = tmp_path / "broken.hdr"
    broken.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n")
    job = finished(LightJob(broken, 8, "instant"))
    assert job.result is None and job.error.startswith(str(broken))


def test_one_worker_serves_the_window_s_jobs_one_after_another(tmp_path, monkeypatch):
    """The window's worker is one child for every fit (torch imported once, when it starts, which the
    window may ask for ahead of the first job): after a bad request
    the same child fits the next map; a stopped job kills it, and the next job starts a new one."""
    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache"))
    worker = ChildWorker()
    try:
        worker.start()  # started ahead (the window's file browser opened): the first job finds it
        pid = worker._proc.pid
        worker.start()
        assert worker._proc.pid == pid
        with worker._lock:  # a request under way holds the lock: start() returns at once, never waits on it
            waiter = threading.Thread(target=worker.start)
            waiter.start()
            waiter.join(10.0)
            assert not waiter.is_alive()
        good = shutil.copyfile(asset_dir() / "envmaps" / "studio_small_03_256.hdr", tmp_path / "studio.hdr")
        job = finished(LightJob(good, 4, "instant", worker=worker))
        assert job.error is None and job.result.how == "fitted" and worker._proc.pid == pid
        try:
            worker.request({"what": "lights", "map": str(tmp_path / "missing.hdr"), "n": 4, "method": "instant"},
                           None, lambda said: None, lambda: None)
        except InputError as exc:
            assert "missing.hdr" in str(exc)
        else:
            raise AssertionError("a missing map gave no error")
        job = finished(LightJob(shutil.copyfile(good, tmp_path / "again.hdr"), 5, "instant", worker=worker))
        assert job.error is None and job.result.how == "fitted" and worker._proc.pid == pid
        other = shutil.copyfile(asset_dir() / "envmaps" / "venice_sunset_256.hdr", tmp_path / "sunset.hdr")
        job = LightJob(other, 4, "instant", worker=worker)
        assert job.stop(60.0) and job.result is None and job.error is None  # stopped: no result, no error
        job = finished(LightJob(other, 4, "instant", worker=worker))
        assert job.result.how == "fitted" and worker._proc.pid != pid
    finally:
        worker.close()
    assert worker._proc is None


def test_a_saved_frame_is_written_on_a_thread_whole_or_said_in_one_line(tmp_path):
    from viewer.app.jobs import SaveJob
    from viewer.files.imageio import read_exr, read_png

    display = np.full((6, 8, 4), 128, np.uint8)
    hdr = np.full((6, 8, 3), 2.5, np.float32)
    job = finished(SaveJob(tmp_path / "relight-1", display, hdr, '{"look": {}}\n'))
    assert job.error is None and job.result == tmp_path / "relight-1.png"
    assert read_png(job.result).shape[:2] == (6, 8) and np.allclose(read_exr(tmp_path / "relight-1.exr")[..., :3], 2.5)
    assert (tmp_path / "relight-1.json").read_text() == '{"look": {}}\n'
    blocked = tmp_path / "file"
    blocked.write_text("a file where the folder should be")
    job = finished(SaveJob(blocked / "relight-2", display, hdr, "{}"))
    assert job.result is None and job.error.startswith("saving relight-2 failed") and "\n" not in job.error
    assert blocked.read_text() == "a file where the folder should be"  # nothing the user had is touched
