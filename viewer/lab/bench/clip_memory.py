"""``relight bench clip-memory``: the peak memory of relighting a clip, at two lengths (whether it is
independent of the clip's length: within 10 % between 10 s and 60 s clips).

Each clip is made here from the bundled photo: its person seen through a window that pans back and
forth across it (the frames differ, the person is always there), at ``fps`` frames a second, so the
two lengths differ only in their frame count. Each is relit end to end by the real command (``relight
render CLIP --env MAP -o OUT.mp4``: decode, inference into a clip bundle, relighting, the MP4) in a
child process of its own. The peak is the most the child and its own children (the inference's child
that ``relight render CLIP`` starts, :mod:`viewer.photo.clip_follow`) held together, their resident sizes
summed every ``SAMPLE_SECONDS``; the largest one process held is read from the kernel when the child
ends (``wait4``'s resource usage: the child and the children it waited for, the largest of them).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import write_text

LENGTHS = (10.0, 60.0)  # seconds
FPS = 5.0  # the frames a second of the made clips (their frame counts: 50 and 300)
SIZE = (320, 480)  # width, height of the made clips' frames
SAMPLE_SECONDS = 0.2  # how often the process tree's resident memory is summed


def tree_resident(pid: int) -> int:
    """Bytes resident in process ``pid`` and its descendants now (/proc)."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    from viewer.memory_needs import resident_bytes

    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        total += resident_bytes(p) or 0  # (one gone meanwhile holds nothing)
        todo += children.get(p, [])
    return total


class TreePeak:
    """The most process ``pid`` and its descendants held together, sampled every ``SAMPLE_SECONDS`` on a
    thread until :meth:`stop` (the process itself is left for its parent to wait for)."""

    def __init__(self, pid: int):
        import threading

        self.pid, self.most = pid, 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()

    def _sample(self) -> None:
        while not self._stop.is_set():
            self.most = max(self.most, tree_resident(self.pid))
            self._stop.wait(SAMPLE_SECONDS)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def panning_clip(path: Path, seconds: float, fps: float = FPS, size: tuple = SIZE) -> Path:
    """An H.264 MP4 of ``seconds`` at ``fps``: the bundled photo's person, the window panning 2 px a
    frame back and forth over up to 40 px (what the photo's width leaves)."""
    import av

    from viewer.photo.frames import read_photo
    from viewer.resize import resize
    from viewer.resources import asset_dir

    photo = read_photo(asset_dir() / "photos/underpass.jpg", [])
    w, h = size
    scale = 1.05 * h / photo.shape[0]
    big = resize(photo, (round(photo.shape[1] * scale), round(photo.shape[0] * scale)))
    span = min(40, big.shape[1] - w)  # the pan's width
    x0 = (big.shape[1] - w - span) // 2
    count = int(round(seconds * fps))
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.mp4")
    with av.open(str(tmp), "w") as out:
        stream = out.add_stream("libx264", rate=int(round(fps)))
        stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p"
        for i in range(count):
            x = x0 + abs((2 * i) % (2 * span) - span) if span > 0 else x0
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(big[:h, x:x + w]), format="rgb24")
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    os.replace(tmp, path)
    return path


def run_clip_memory_benchmark(envmap: Path, out_dir, lengths=LENGTHS, output=None) -> dict:
    """Each length's clip made and relit in a child process; figures to ``output`` (JSON)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    output = Path(output) if output is not None else out_dir / "clip_memory.json"
    result = {"map": envmap.name, "fps": FPS, "size": list(SIZE), "runs": []}
    for seconds in sorted(lengths):
        clip = panning_clip(out_dir / f"panning_{seconds:g}s.mp4", seconds)
        relit = out_dir / f"panning_{seconds:g}s_relit.mp4"
        relit.unlink(missing_ok=True)
        env = {**os.environ, "RELIGHT_CACHE": str(out_dir / "cache" / "lights")}
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "viewer.cli.main", "render", str(clip), "--env", str(envmap), "-o", str(relit)],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
        sampler = TreePeak(proc.pid)
        err = proc.stderr.read()
        _, status, usage = os.wait4(proc.pid, 0)
        sampler.stop()
        proc.returncode = os.waitstatus_to_exitcode(status)
        seconds_taken = time.perf_counter() - t0
        if proc.returncode != 0:
            raise RuntimeError(f"relight render {clip.name} failed: {err.strip().splitlines()[-1:]}")
        peak = sampler.most / 2 ** 30
        frames = int(round(seconds * FPS))
        run = {"seconds": seconds, "frames": frames, "peak_rss_gb": round(peak, 3),
               "largest_process_gb": round(usage.ru_maxrss / 2 ** 20, 3), "wall_seconds": round(seconds_taken, 1),
               "frames_per_minute": round(60 * frames / seconds_taken, 2)}
        result["runs"].append(run)
        print(f"{seconds:g} s ({frames} frames): peak {peak:.3f} GB, {seconds_taken:.0f} s", flush=True)
        write_text(output, json.dumps(result, indent=1) + "\n")
    first, last = result["runs"][0]["peak_rss_gb"], result["runs"][-1]["peak_rss_gb"]
    result["growth"] = round(last / first - 1.0, 4)
    write_text(output, json.dumps(result, indent=1) + "\n")
    return result
