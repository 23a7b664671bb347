"""A clip's relit pictures, prepared ahead in the window (``relight view CLIP``): what playing draws.

Relighting a frame as it falls due showed about 1.3 of a 720p clip's 24 frames a second on two cores
with llvmpipe: each frame's scene read (~0.1 s, on a thread), its engine made (~0.15-0.25 s), the map
given (~0.02-0.07 s) and its passes run (~0.45 s). Drawing a finished picture is a texture upload (~5 ms).
What a frame shows depends only on its index and the lighting (:meth:`Session.lighting_key`, the map,
the quality), so each frame is relit once into its picture (uint8 RGB, as the window draws it) while
the window has nothing else to do, one budgeted slice of work between its frames (GL stays on the
window's thread: another thread cannot have a context beside the window's, ../shared/docs/STACK.md), and
playing draws the pictures at the clip's own rate. A change of the lighting starts them again; a frame
not ready yet is relit live (:mod:`viewer.app.timeline`), as before.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from viewer.app.picture_texture import PictureTexture
from viewer.lighting.placed_lights import to_area_lights

MEMORY = 2 << 30  # bytes of pictures kept (~770 frames at 1280x720): the frames past it are relit live


class RelitFrames:
    def __init__(self, ctx, timeline):
        self.ctx = ctx
        self.timeline = timeline  # the clip's frames (what each index shows) and the sizes they are read at
        self.pictures: dict[int, np.ndarray] = {}  # output frame -> its picture under :attr:`key`'s lighting
        self.key: bytes | None = None  # the lighting the pictures are of (None: none can be, :meth:`follow`)
        self.error = ""  # a frame's scene that could not be read: nothing more is prepared (the live frame says why)
        self._engine = None  # (frame with a person, its Engine) being relit
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="relit-frames")
        self._read: tuple[int, Future] | None = None  # (frame with a person, its scene being read)
        self._texture = PictureTexture(ctx)  # keyed by (frame, lighting)
        self.wake = lambda: None  # called when a scene is read (the window's wake: the loop sleeps meanwhile)

    def follow(self, session):
        """The pictures kept only while the lighting is theirs: another look, lights, map or quality drops
        them (and the engine: its map or options may be another's). Refined shadows come from a network
        on a thread, per frame: those frames are relit live."""
        key = None
        if session.look.shadows != "refined":
            key = session.lighting_key() + repr((id(session.environment), session.options)).encode()
        if key != self.key:
            self.key = key
            self.pictures = {}
            self._release_engine()

    def ready(self, index: int) -> bool:
        return self.key is not None and index in self.pictures

    @property
    def count(self) -> int:
        return len(self.pictures)

    def _next(self) -> int | None:
        """The frame to relit next: the first not ready from the one asked for on, then from the clip's
        start; None when all are, or the memory for them is spent."""
        t = self.timeline
        if self.key is None or self.error or sum(p.nbytes for p in self.pictures.values()) >= MEMORY:
            return None
        order = list(range(t.index, t.count)) + list(range(t.index))
        return next((k for k in order if k not in self.pictures), None)

    def _scene(self, person: int):
        """Frame ``person``'s scene once read on the pool, else None (its read started)."""
        if self._read is None or self._read[0] != person:
            future = self._pool.submit(self.timeline.frames.scene, person, self.timeline.sizes)
            future.add_done_callback(lambda _: self.wake())
            self._read = (person, future)
        future = self._read[1]
        if not future.done():
            return None
        try:
            return future.result()
        except Exception as exc:  # (the bundle changed on disk) the live frame reads it again and reports it
            self.error = f"frame {person + 1}: {type(exc).__name__}: {exc}"
            return None

    def prepare(self, session, budget: float) -> bool:
        """One slice of the next frame's relighting (its engine made, or ``budget`` seconds of its passes);
        False when there was nothing to do (all ready, or a scene still being read: its read wakes the window)."""
        from viewer.gl import Engine

        k = self._next()
        if k is None:
            return False
        frames = self.timeline.frames
        index, person = frames.shown(k)
        if self._engine is None or self._engine[0] != person:
            scene = self._scene(person)
            if scene is None:
                return False
            self._release_engine()
            engine = Engine(self.ctx, scene, session.options, frames.background_camera(person))
            if session.environment is not None:
                engine.set_environment(session.environment)
            self._engine = (person, engine)
            return True
        engine = self._engine[1]
        engine.set_lights(session.map_lights, to_area_lights(session.placed))
        engine.set_look(session.look.on_frame(frames.camera_turn(index, person), frames.camera_height(person)))
        engine.render(budget)
        if engine.complete:
            self.pictures[k] = np.ascontiguousarray(self.timeline.picture_of(engine, index, person))
        return True

    def texture(self, index: int):
        """Frame ``index``'s picture in the window's texture (written again only for another frame or lighting)."""
        return self._texture.show((index, self.key), lambda: self.pictures[index])

    @property
    def own_texture(self):
        """The texture last drawn from the pictures (None before one was)."""
        return self._texture.texture

    def _release_engine(self):
        if self._engine is not None:
            self._engine[1].release()
            self._engine = None

    def release(self):
        self.wake = lambda: None
        self._release_engine()
        self._texture.release()
        self._pool.shutdown(wait=False, cancel_futures=True)  # a read under way ends on its own (numpy, no GL)
