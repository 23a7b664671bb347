"""Memory budgets: what a command will need, estimated from the sizes asked before anything large
is allocated, held to what this machine can give.

The budget is 80 % of the memory available when the command starts (``MemAvailable``, bounded by
the cgroup's limit): past it the command is refused in one line that says what would fit, instead
of being killed by the kernel or thrashing the machine. The estimates are peak resident sizes
measured with ``/usr/bin/time -f %M`` on this project's 2-core machine (docs/robustness.md) and
checked by ``relight bench robustness``, which records every case's peak beside the budget.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

from viewer.errors import InputError

BUDGET_SHARE = 0.8
GB = 1e9

# a frame rendered from a scene bundle (render, video, the viewer): measured on a photo bundle
# (maps 391x588 to 2724x4096, frame 1362x2048) and the sample (maps = frame, 256 to 2048 px):
# 0.66 / 0.99 / 2.41 / 7.48 GB at maps of 0.23 / 0.70 / 2.79 / 11.2 MP; the frame adds ~110 B a pixel
RENDER_BASE = 0.35 * GB
RENDER_PER_MAP_PIXEL = 610
RENDER_PER_FRAME_PIXEL = 110

# a photo inferred into a bundle: measured on a 12000x8011 photo, frame 2048 and 4096 px long:
# 2.07 and 4.36 GB (at 12000 px long the kernel killed it at 24.4 GB)
INFER_BASE = 1.0 * GB
INFER_PER_PHOTO_PIXEL = 6  # the decoded photo and its mask
INFER_PER_FRAME_PIXEL = 275


def _meminfo_available() -> int | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _cgroup_room() -> int | None:
    """What the cgroup (v2) still lets this process group take, if it sets a limit."""
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit == "max":
            return None
        return int(limit) - int(Path("/sys/fs/cgroup/memory.current").read_text().strip())
    except (OSError, ValueError):
        return None


def memory_budget() -> int:
    """Bytes a command may plan to use: :data:`BUDGET_SHARE` of what is available now."""
    room = [v for v in (_meminfo_available(), _cgroup_room()) if v is not None]
    return int(BUDGET_SHARE * min(room)) if room else int(8 * GB)


def require(need: float, what: str, advice: str, path=None) -> None:
    """Refuse in one line when ``need`` bytes are past the budget: what would need them, how much
    is free, and ``advice`` (what would fit)."""
    budget = memory_budget()
    if need > budget:
        raise InputError(path, f"{what} would need about {need / GB:.1f} GB of memory, more than the "
                               f"{budget / GB:.1f} GB this machine can give now ({advice})")


def render_bytes(map_pixels: int, frame_pixels: int) -> float:
    """Peak memory of rendering a scene whose maps and frame have these many pixels."""
    return RENDER_BASE + RENDER_PER_MAP_PIXEL * map_pixels + RENDER_PER_FRAME_PIXEL * frame_pixels


def _largest_side(fixed: float, per_pixel: float, aspect: float) -> int:
    """The largest longer side (a multiple of 256, at least 16) of an image whose shorter side is
    ``aspect`` times it and whose ``per_pixel`` bytes fit the budget beside ``fixed`` bytes."""
    side = int((max(memory_budget() - fixed, 0) / (per_pixel * aspect)) ** 0.5)
    return max(side // 256 * 256, 16)


def largest_render_size(aspect: float, frame_pixels: int) -> int:
    """The largest ``--size`` (the maps' longer side) whose render fits the budget, for maps whose
    shorter side is ``aspect`` times the longer."""
    return _largest_side(RENDER_BASE + RENDER_PER_FRAME_PIXEL * frame_pixels, RENDER_PER_MAP_PIXEL, aspect)


def infer_bytes(photo_pixels: int, frame_pixels: int) -> float:
    """Peak memory of inferring a bundle from a photo of this many pixels into a frame of these."""
    return INFER_BASE + INFER_PER_PHOTO_PIXEL * photo_pixels + INFER_PER_FRAME_PIXEL * frame_pixels


def largest_frame_side(photo_pixels: int, aspect: float) -> int:
    """The largest ``--max-size`` whose inference fits the budget."""
    return _largest_side(INFER_BASE + INFER_PER_PHOTO_PIXEL * photo_pixels, INFER_PER_FRAME_PIXEL, aspect)


def resident_bytes(pid: int | str = "self") -> int | None:
    """Process ``pid``'s resident memory now (Linux's /proc/PID/statm; this process's by default),
    None where it cannot be read."""
    import os

    try:
        return int(Path(f"/proc/{pid}/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


TRIM_GROWTH = 1.2  # the resident size a clip's loop lets grow over its size after the first frames before it hands memory back


@contextmanager
def frames_freed():
    """For a loop over a clip's frames: yields ``after_frame()``, to call between two frames. It
    collects the cyclic garbage and, when the process's resident size has grown past ``TRIM_GROWTH``
    times what it was after the second frame (or after the last trim, if more), hands the C heap's free memory back to the system
    (glibc's ``malloc_trim``): each frame builds and frees an engine and its maps, and without this
    the resident size crept up with the clip's length (rendering 300 frames: peak 693 MB against
    595 MB after 50; with a trim after every frame 448 MB, flat after the first 50, measured on
    ``relight bench clip-memory``'s 60-s clip). A trim after *every* frame cost its own: the next
    frame's arrays came back as fresh pages, faulted in and zeroed by the kernel (30 frames of a
    1280x720 clip inferred: 2.08 million page faults, 12.3 s of system time, 63.7 s; trimmed only
    past the bound: 0.86 million, 4.6 s, 55.6 s, 13 % faster). What is alive after the first frame
    (the modules, the networks, the face and pose models, the GL context) lives as long as the loop:
    it is frozen out of the collections (``gc.freeze``; a full collection over it took 0.16 s a frame)
    and thawed when the loop ends."""
    import ctypes
    import gc

    frozen = False
    frames = 0
    bound: float | None = None

    def after_frame() -> None:
        nonlocal frozen, frames, bound
        gc.collect()
        if not frozen:
            gc.freeze()
            frozen = True
        frames += 1
        now = resident_bytes()
        if frames == 2 and now is not None:
            bound = TRIM_GROWTH * now
        if now is None or (bound is not None and now > bound):
            try:
                ctypes.CDLL("libc.so.6").malloc_trim(0)
            except (OSError, AttributeError):  # not glibc: the collection alone
                pass
            after = resident_bytes()
            if bound is not None and after is not None:  # what is alive grew (a person came in): not trimmed every frame for it
                bound = max(bound, TRIM_GROWTH * after)

    try:
        yield after_frame
    finally:
        if frozen:
            gc.unfreeze()
