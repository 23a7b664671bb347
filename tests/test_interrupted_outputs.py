"""Interrupted work never damages what the user had: real processes are killed (SIGINT, SIGKILL)
at several moments while they write a video or a frame, and the target is then either the old
file or the complete new one (a video cut short stays under its own ``.partial.mp4`` name)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from viewer.output.video import partial_path, read_video

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "assets" / "sample_scene"
LIGHTS = ROOT / "assets" / "envmaps" / "venice_sunset_256.lights.json"


def relight(*args) -> list[str]:
    return [sys.executable, "-m", "viewer.cli.main", *map(str, args)]


# the child started with a limit or a signal's default set in a one-threaded Python that then becomes
# it (a preexec_fn in the test run's threaded process can deadlock the fork)
PREPARED = ("import os, resource, signal, sys; limit = int(sys.argv[1]); "
            "limit and resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit)); "
            "signal.signal(signal.SIGINT, signal.SIG_DFL); os.execv(sys.executable, [sys.executable, *sys.argv[2:]])")


def prepared(command: list[str], file_size_limit: int = 0) -> list[str]:
    """``command`` with Ctrl-C interrupting (a test run may have inherited SIGINT ignored, and a Python
    started with SIGINT ignored never raises KeyboardInterrupt) and files limited to ``file_size_limit``
    bytes (0: no limit)."""
    return [sys.executable, "-c", PREPARED, str(file_size_limit), *command[1:]]


def wait_for(condition, timeout=120.0):
    start = time.monotonic()
    while not condition():
        if time.monotonic() - start > timeout:
            raise AssertionError("timed out")
        time.sleep(0.02)


@pytest.fixture(scope="module")
def earlier_video(tmp_path_factory):
    path = tmp_path_factory.mktemp("video") / "turn.mp4"
    res = subprocess.run(relight("render", SCENE, LIGHTS, "--size", "96", "--frames", "6", "-o", path), capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    return path, path.read_bytes()


@pytest.mark.parametrize("sig, after_frames", [(signal.SIGINT, 10), (signal.SIGKILL, 0), (signal.SIGKILL, 30)])
def test_an_interrupted_video_leaves_the_earlier_one_whole(earlier_video, sig, after_frames):
    path, before = earlier_video
    partial = partial_path(path)
    partial.unlink(missing_ok=True)
    proc = subprocess.Popen(prepared(relight("render", SCENE, LIGHTS, "--size", "96", "--frames", "2000", "--yaw", "40", "-o", path)),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for(lambda: partial.exists())
        if after_frames:  # a fragment holds one second (30 frames); wait until the file has grown past its header
            size = partial.stat().st_size
            wait_for(lambda: partial.stat().st_size > size + 100 * after_frames)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert path.read_bytes() == before, err[-500:]  # the earlier video, untouched
    if sig == signal.SIGINT:
        last = err.strip().splitlines()[-1]  # (above it: the progress bar)
        assert proc.returncode == 130 and err.count("relight:") == 1 and "Traceback" not in err
        assert last.startswith("relight: interrupted") and "turn.partial.mp4" in last and "left as it was" in last
        frames, _ = read_video(partial)  # what was recorded so far plays
        assert len(frames) > 0
    else:
        assert proc.returncode == -signal.SIGKILL
    partial.unlink(missing_ok=True)


def test_a_killed_frame_write_leaves_the_old_frame_or_the_new_one(tmp_path):
    """SIGKILL at several moments of ``render -o x.png``: x.png (and its EXR) are always whole
    files, the old ones or the new ones, never truncated."""
    out = tmp_path / "x.png"
    args = ("render", SCENE, LIGHTS, "--size", "128")
    assert subprocess.run(relight(*args, "-o", out), capture_output=True).returncode == 0
    old = out.read_bytes(), out.with_suffix(".exr").read_bytes()
    new_dir = tmp_path / "new"
    assert subprocess.run(relight(*args, "--yaw", "90", "-o", new_dir / "x.png"), capture_output=True).returncode == 0
    new = (new_dir / "x.png").read_bytes(), (new_dir / "x.exr").read_bytes()
    assert new != old
    start = time.monotonic()
    complete = subprocess.run(relight(*args, "--yaw", "90", "-o", tmp_path / "timing.png"), capture_output=True)
    seconds = time.monotonic() - start
    assert complete.returncode == 0
    seen = set()
    for fraction in (0.3, 0.6, 0.8, 0.9, 0.95, 1.0):
        proc = subprocess.Popen(relight(*args, "--yaw", "90", "-o", out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(seconds * fraction)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        now = out.read_bytes(), out.with_suffix(".exr").read_bytes()
        assert now[0] in (old[0], new[0]) and now[1] in (old[1], new[1])
        seen.add((now[0] == new[0], now[1] == new[1]))
        for stray in tmp_path.glob(".x.*.tmp"):  # a killed writer's temporary file is the only trace
            stray.unlink()
        out.write_bytes(old[0])
        out.with_suffix(".exr").write_bytes(old[1])
    assert (False, False) in seen  # killed before anything was replaced at least once
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".mp4")]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_end_a_render_like_ctrl_c(tmp_path, sig):
    """SIGTERM (a service stopping) and SIGHUP (a terminal closing) at several moments of ``render
    -o x.png``: one line, no temporary file left, the old PNG and EXR kept or both new."""
    out = tmp_path / "x.png"
    args = ("render", SCENE, LIGHTS, "--size", "128")
    assert subprocess.run(relight(*args, "-o", out), capture_output=True).returncode == 0
    old = out.read_bytes(), out.with_suffix(".exr").read_bytes()
    start = time.monotonic()
    assert subprocess.run(relight(*args, "--yaw", "90", "-o", tmp_path / "timing.png"), capture_output=True).returncode == 0
    seconds = time.monotonic() - start
    interrupted = 0
    for fraction in (0.4, 0.7, 0.9, 0.97):
        proc = subprocess.Popen(relight(*args, "--yaw", "90", "-o", out), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True)
        time.sleep(seconds * fraction)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
        if proc.returncode == 130:
            interrupted += 1
            assert err.strip().splitlines()[-1].startswith(f"relight: interrupted ({sig.name})"), err
        else:  # done before the signal, or ended by it while Python itself was starting (nothing written yet)
            assert proc.returncode in (0, -sig), (proc.returncode, err)
        assert "Traceback" not in err
        now = out.read_bytes(), out.with_suffix(".exr").read_bytes()
        assert now == old or (now[0] != old[0] and now[1] != old[1])  # both old, or both new: never a mix
        assert not list(tmp_path.glob(".x.*")), list(tmp_path.glob(".x.*"))  # no temporary file left
        out.write_bytes(old[0])
        out.with_suffix(".exr").write_bytes(old[1])
    assert interrupted >= 1


@pytest.fixture
def small_disk(tmp_path):
    """A folder on a 400 KB file system (a tmpfs, mounted as root; otherwise the children may write
    at most 100 KB to any file, RLIMIT_FSIZE: the same failed write, EFBIG instead of ENOSPC), and that
    limit (None as root)."""
    folder = tmp_path / "small"
    folder.mkdir()
    if os.geteuid() == 0:
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(folder)], check=True)
        try:
            yield folder, None
        finally:
            subprocess.run(["umount", str(folder)], check=True)
    else:
        yield folder, 100_000  # bytes


def test_a_full_disk_ends_in_one_line_naming_the_file_and_keeps_the_old_outputs(small_disk):
    folder, limit = small_disk
    out = folder / "x.png"
    args = ("render", SCENE, LIGHTS, "-o", out)
    assert subprocess.run(relight(*args, "--size", "64"), capture_output=True).returncode == 0
    old = {p.name: p.read_bytes() for p in folder.iterdir()}
    if limit is None:  # what is left of the disk: less than the new frame's PNG and EXR need
        free = os.statvfs(folder).f_bavail * os.statvfs(folder).f_frsize
        (folder / "filler").write_bytes(os.urandom(max(free - 40_000, 0)))
        old["filler"] = (folder / "filler").read_bytes()
    proc = subprocess.run(prepared(relight(*args, "--size", "512", "--yaw", "90"), limit or 0), capture_output=True, text=True)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert lines[0].startswith(f"relight: error: {folder}/x.") and ("No space left" in lines[0] or "too large" in lines[0])
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == old  # the old frame whole, no temporary file
