"""The drag preview: the scene resampled to a coarser *level* (fewer work pixels, a smaller frame,
coarser shadow maps and ground shadow), and the pace that picks the level from the measured times
of the frames being dragged.

Why levels chosen by measurement: what a frame costs depends on the photo (its frame's size, the
person's share of it), on the machine and on what else runs. On this 2-core machine with llvmpipe
(docs/viewer.md, "A fluid drag"), a 2048-pixel photo's preview took 61 ms at the finest level and 31
ms at the middle one idle, 76 and 36 ms beside one busy process; a fixed level is either too slow
there or needlessly coarse on a fast machine. :class:`PreviewPace` steps to a coarser level when
the frames of a drag are slower than the frame budget and back to a finer one when a drag starts
with room for it, so a drag stays at 24 frames a second or more wherever the machine can, at the
finest level that does. The current level's engine and its neighbours' are made, and drawn once, in
idle frames before the pace can need them (:meth:`PreviewEngines.cold`), so a step of one level
mid-drag costs no frame (a second step in the same drag, or a drag within a second or two of a new
map, may pay a first draw).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from viewer.gl import Engine, EngineOptions
from viewer.resize import scaled_size
from viewer.scene.bundle import Scene
from viewer.scene.resampling import resample_scene


@dataclass(frozen=True)
class PreviewLevel:
    work: int  # the maps' longer side (pixels)
    frame: int  # a photo's frame's longer side (pixels): the photo's detail, most of a frame's cost
    shadow_resolution: int  # texels of each light's shadow map
    shadow_step: int  # the shadow casters' depth mesh: a triangle every this many pixels of ``work``
    ground_scale: int  # the ground shadow at 1 / this of the work resolution (EngineOptions.ground_scale)


# finest first; each about 1.3-2x cheaper than the one before it (measured, docs/viewer.md; a coarser
# one gained little: its passes are one llvmpipe tile each, one thread). The casters' step 3 at 256
# pixels takes 10-25 % off a frame against the final engine's 2: hard shadows while the light moves
# lose their finest detail, the full frame after the release has it back. The ground shadow at an
# eighth of 128 pixels lit the backdrop 0.5/255 more than the final frame's (tests/test_session.py:
# 0.09 at a sixth).
PREVIEW_LEVELS = (
    PreviewLevel(256, 768, 256, 3, 4),
    PreviewLevel(192, 576, 256, 3, 6),
    PreviewLevel(160, 480, 256, 3, 8),
    PreviewLevel(128, 384, 256, 4, 6),
)
START_LEVEL = 2  # the first drag's level, before any frame was measured (one step from the coarsest, two from the finest)
STILL_SECONDS = 0.25  # a drag that has not moved for this long renders at full quality
SWAP_BUDGET = 0.06  # seconds of engine work a frame gives a new map or person before the frame is shown
FRAME_BUDGET_MS = 36.0  # a dragged frame's median, whole window frame: 24 fps (41.7 ms) with room for the slower ones
SAMPLES = 3  # dragged frames measured at a level before it is judged
FINER_ROOM = 0.55  # a drag starts one level finer when the last one's frames took under this share of the budget


class PreviewPace:
    """The level of the drag preview, from the measured times of the dragged frames (window frames,
    events to swap): coarser as soon as :data:`SAMPLES` frames at a level have a median over the
    budget, finer only at the start of a drag, when the previous one's median left room."""

    def __init__(self, levels: int = len(PREVIEW_LEVELS), start: int = START_LEVEL, budget_ms: float = FRAME_BUDGET_MS):
        self.levels = levels
        self.level = min(start, levels - 1)
        self.budget_ms = budget_ms
        self.recent: deque = deque(maxlen=SAMPLES)  # frame times at the current level (ms)
        self.last_median: float | None = None  # the median of the previous drag's last frames at this level

    def start_drag(self) -> None:
        """A drag starts: one level finer if the last one had room for it."""
        if self.last_median is not None and self.last_median < FINER_ROOM * self.budget_ms and self.level > 0:
            self.level -= 1
            self.last_median = None
        self.recent.clear()

    def record(self, ms: float) -> None:
        """A dragged frame at the current level took ``ms``."""
        self.recent.append(float(ms))
        if len(self.recent) < SAMPLES:
            return
        median = float(np.median(self.recent))
        if median > self.budget_ms and self.level < self.levels - 1:
            self.level += 1
            self.recent.clear()
            self.last_median = None
        else:
            self.last_median = median


def preview_scene(scene: Scene, level: PreviewLevel) -> Scene:
    """The scene at a preview level: its maps resampled to about ``level.work`` pixels (the frame's
    field of view kept), a photo's frame to about ``level.frame`` (:func:`no_power_of_two`)."""
    small = scene
    if max(small.width, small.height) > level.work:
        small = resample_scene(small, no_power_of_two((small.width, small.height), level.work), keep_frame=True)
    if small.frame is not None and max(small.output_size) > level.frame:
        size = scaled_size(small.output_size, no_power_of_two(small.output_size, level.frame))
        small = replace(small, frame=small.frame.resized(size))
    return small


def no_power_of_two(size: tuple[int, int], longest: int) -> int:
    """The longer side, ``longest`` or a few pixels less, at which neither side of ``size`` (w, h)
    scaled to it is a power of two. llvmpipe compiles a shader variant for each bound texture's
    power-of-two-ness, side by side: every level's textures of one kind, so a level's first frame
    reuses the variants another level compiled (a level whose composite was 128 pixels high built its
    mip levels in 49 ms against 1-2 ms, in an idle frame of the window)."""
    for n in range(longest, max(longest - 8, 1), -1):
        if not any(v & (v - 1) == 0 for v in scaled_size(size, n)):
            return n
    return longest


def preview_options(options: EngineOptions, scene: Scene, level: PreviewLevel) -> EngineOptions:
    """The final engine's options at a preview level (for ``scene``, the level's resampled scene)."""
    step = max(1, round(level.shadow_step * max(scene.width, scene.height) / level.work))
    return replace(options, shadow_resolution=min(level.shadow_resolution, options.shadow_resolution), shadow_step=step,
                   ground_scale=level.ground_scale)


class PreviewEngines:
    """The preview's engines of one scene, one per level, made on demand and given the current map
    when next used (a new map is blurred and uploaded for the final engine in the frame that shows it,
    for each preview engine in an idle frame after it: :meth:`cold`)."""

    def __init__(self, ctx, scene: Scene, options: EngineOptions, background_camera=None, levels=PREVIEW_LEVELS):
        self.ctx, self.scene, self.options, self.levels = ctx, scene, options, levels
        self.background_camera = background_camera  # the final engine's (Session.set_scene)
        self.engines: dict[int, Engine] = {}
        self.environment: np.ndarray | None = None
        self._version = 0  # of the map; each engine's is in _has
        self._has: dict[int, int] = {}
        self.drawn: set[int] = set()  # levels whose engine has the current map and drew a frame with it

    def make(self, level: int) -> Engine:
        """The level's engine, made if need be (the scene resampled; the map not given yet)."""
        eng = self.engines.get(level)
        if eng is None:
            small = preview_scene(self.scene, self.levels[level])
            eng = self.engines[level] = Engine(self.ctx, small, preview_options(self.options, small, self.levels[level]),
                                               self.background_camera)
        return eng

    def has_map(self, level: int) -> bool:
        """Whether the level's engine has the current map."""
        return self._has.get(level) == self._version

    def engine(self, level: int) -> Engine:
        """The level's engine, made and given the current map if need be."""
        eng = self.make(level)
        if not self.has_map(level):
            if self.environment is not None:
                eng.set_environment(self.environment)
            self._has[level] = self._version
        return eng

    def warm(self, level: int, draw) -> bool:
        """One step towards the engines the next drag may need from ``level`` (its own and its
        neighbours', :meth:`cold`; a first frame would otherwise pay ~0.1-0.6 s in a dragged frame):
        make one, give it the map, or draw its first frame (``draw(engine)``: True once complete, the rest
        at the next call), one per call (an idle frame each); True when there was one to take."""
        level = self.cold(level)
        if level is None:
            return False
        if level not in self.engines:
            self.make(level)  # the maps resampled and the engine made (~40-60 ms at 2 MP)
        elif not self.has_map(level):
            self.engine(level)  # the map blurred and uploaded (~15-20 ms for a 1k map)
        elif draw(self.engine(level)):
            self.drawn.add(level)
        return True

    def set_environment(self, environment: np.ndarray | None):
        self.environment = environment
        self._version += 1
        self.drawn.clear()

    def cold(self, level: int) -> int | None:
        """The level, of ``level`` and its neighbours, whose engine is not made, has an older map or
        has not drawn a frame yet (None: none); the others' engines are released (what a level change
        may need is kept, no more)."""
        near = [lv for lv in (level, level + 1, level - 1) if 0 <= lv < len(self.levels)]
        for lv in [lv for lv in self.engines if lv not in near]:
            self.engines.pop(lv).release()
            self._has.pop(lv, None)
            self.drawn.discard(lv)
        return next((lv for lv in near if lv not in self.drawn), None)

    def release(self):
        for eng in self.engines.values():
            eng.release()
        self.engines.clear()
        self._has.clear()
        self.drawn.clear()
