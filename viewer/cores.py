"""The cores this program really gets, and the threads each compute stage may use.

Why: on shared cores a thread pool sized to the machine collapses. torch's OpenMP workers meet at a
barrier after every operation, so one worker descheduled by another process stalls all of them:
``relight fit-lights`` of a 1k map took 3.0 s idle and 15.3 s beside two busy processes on this
2-core machine, 4.7 s there with one thread (../shared/docs/STACK.md). So before heavy work a
process asks :func:`work_threads` how many cores are idle *now* (``/proc/stat`` over a short
window, bounded by the CPU affinity and a cgroup quota) and sizes every pool to that:
torch's intra-op threads, OpenCV's, OpenBLAS's and OpenMP's (through ``threadpoolctl``, the
scikit-learn project's library for exactly this, rather than each library's environment variable,
which is read once at import), and llvmpipe's rasterizer threads (``LP_NUM_THREADS``, read when a
GL context is made, so it is set in the environment before the first one).

The whole program shares one budget: the child process that infers photos and fits maps for the
viewer's window sizes itself to the idle cores less ``WINDOW_CORES`` (``reserve``), kept for the
window's frames. The window's own llvmpipe threads are the cores it may use, not the idle ones
(viewer/cli/main.py): its frames are short bursts whose threads do not wait on each other between
operations, and two threads measured faster than one even beside a busy process (docs/viewer.md).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

SAMPLE_SECONDS = 0.05  # the window over which idle time is measured (5 jiffies at 100 Hz)
WINDOW_CORES = 1  # what the viewer's window keeps for its own frames while its child works


def allowed_cores() -> int:
    """The cores this process may run on: its CPU affinity, bounded by a cgroup v2 quota."""
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        n = os.cpu_count() or 1
    try:
        quota, period = Path("/sys/fs/cgroup/cpu.max").read_text().split()[:2]
        if quota != "max":
            n = min(n, max(1, int(int(quota) // int(period))))
    except (OSError, ValueError):
        pass
    return max(1, n)


def _busy_idle() -> tuple[int, int] | None:
    try:
        fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    except (OSError, ValueError):
        return None
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)  # idle + iowait
    return sum(fields[:8]) - idle, idle


def idle_cores(seconds: float = SAMPLE_SECONDS) -> float | None:
    """How many cores sat idle over the last ``seconds`` (None where /proc/stat cannot be read)."""
    first = _busy_idle()
    if first is None:
        return None
    time.sleep(seconds)
    second = _busy_idle()
    busy, idle = second[0] - first[0], second[1] - first[1]
    if busy + idle <= 0:
        return None
    return (os.cpu_count() or 1) * idle / (busy + idle)


def work_threads(reserve: int = 0) -> int:
    """Threads for the work about to start: the idle cores (rounded, at most the allowed ones), less
    ``reserve`` kept for another part of the program; at least one."""
    allowed = allowed_cores()
    idle = idle_cores()
    free = allowed if idle is None else min(allowed, int(idle + 0.5))
    return max(1, free - reserve)


def size_pools(threads: int, gl_threads: int | None = None) -> None:
    """Size every compute pool of this process to ``threads``: the libraries loaded now directly,
    those loaded later through the environment they read at load (torch and OpenMP: OMP_NUM_THREADS,
    numba: NUMBA_NUM_THREADS, OpenCV: OPENCV_FOR_THREADS_NUM, llvmpipe: LP_NUM_THREADS, unless the
    user set it, to ``gl_threads`` when given)."""
    for name in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "OPENCV_FOR_THREADS_NUM"):
        os.environ[name] = str(threads)
    os.environ.setdefault("LP_NUM_THREADS", str(gl_threads or threads))
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(threads)
    if "cv2" in sys.modules:
        sys.modules["cv2"].setNumThreads(threads)
    if "numba" in sys.modules:
        numba = sys.modules["numba"]
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=threads)  # OpenBLAS (numpy) and the OpenMP runtimes already loaded
