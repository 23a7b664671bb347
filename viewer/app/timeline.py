"""A clip bundle in the window (``relight view CLIP``): which frame shows, playing or paused.

Playing keeps the clip's own clock: the frame shown is the one due at the time played so far, so a frame
slower to show than the clip's frame interval is skipped over, never slowed down (a software renderer
relights a 720p frame in about 0.7 s; the recording, R, renders every frame). A frame whose relit
picture is ready (:mod:`viewer.app.relit_frames`, prepared while the window is idle) is drawn from it;
one that is not is relit live: its scene read on a thread ahead of the frame that shows it
(:meth:`ClipTimeline.advance`), the next one it will show while playing read behind it. What the slider
and the words say is the frame on screen (:meth:`ClipTimeline.drew`), not the one asked for. The session
keeps the lighting, the user's lights and the look from frame to frame (one exposure for the clip, set
from its first frame when the window opens, the user's after: what the window shows of a frame is what R
records of it, and ``relight render --look`` of the state saved with S); a frame brings its person
(:meth:`Session.set_scene`, with its shot's lens for the map behind) and how far its camera turned
(:attr:`Session.camera_turn`) and how high it stood (:attr:`Session.camera_height`). A frame without the
person shows the new background alone, as the nearest frame with the person sees it (:meth:`ClipTimeline.texture`), as the relit MP4 does
(:mod:`viewer.output.clip_render`).
"""

from __future__ import annotations

import bisect
import time
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from viewer.app.picture_texture import PictureTexture
from viewer.output.clip_frames import ClipFrames, shows_filmed_frame
from viewer.scene.clip_bundle import ClipBundle


class ClipTimeline:
    def __init__(self, ctx, bundle: ClipBundle, sizes: tuple = (None, None)):
        self.ctx = ctx
        self.bundle = bundle
        self.frames = ClipFrames(bundle)
        self.sizes = sizes  # (--size, --max-size) each frame's scene is read with
        self.times = [e.seconds for e in bundle.frames]
        self.shots = len({e.shot for e in bundle.frames})
        self.fps = float(bundle.source.get("fps") or 30.0)
        self.index = 0  # the frame asked for (the slider's, the arrows', the clock's)
        self.current: tuple[int, int] | None = None  # the session's (frame, the frame with a person whose scene renders it)
        self.showing: int | None = None  # the frame whose picture is on screen (drew)
        self.playing = False
        self.every_frame = False  # play every frame (as fast as they are drawn, never faster than the clip), not the clip's clock
        self._clock: tuple[float, float] | None = None  # (perf_counter when play began, the clip's seconds then)
        self._stepped = 0.0  # when every_frame last stepped
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="clip-frames")
        self._loads: dict[int, Future] = {}  # frame -> its scene being read (at most two: the one asked, the next)
        self._texture = PictureTexture(ctx)  # the background alone, for a frame without the person
        self._filmed_frame = None  # ((frame, size), the frame as filmed): a frame without the person under the photo background
        self.shown_at: list[float] = []  # perf_counter of each new frame drawn while playing (its rate)
        self.wake = lambda: None  # called when a frame's scene is read (the window's wake: the loop sleeps meanwhile)

    def began(self, session):
        """The window's first frame: the session was made with frame 0's person's scene and lens."""
        index, person = self.current = self.frames.shown(0)
        session.camera_turn, session.camera_height = self.frames.camera_turn(index, person), self.frames.camera_height(person)

    # ------------------------------------------------------------------ the clock
    @property
    def count(self) -> int:
        return len(self.times)

    @property
    def seconds(self) -> float:
        """The clip's time of the frame asked for."""
        return self.times[self.index]

    def frame_at(self, seconds: float) -> int:
        """The frame due at ``seconds`` of the clip: the last one that starts at or before it."""
        return min(max(bisect.bisect_right(self.times, seconds + 1e-6) - 1, 0), self.count - 1)

    def play(self, playing: bool | None = None):
        """Play (from the start when at the end) or pause; ``None``: the other of the two."""
        playing = not self.playing if playing is None else playing
        if playing and self.index >= self.count - 1:
            self.index = 0
        self.playing = playing
        self._clock = (time.perf_counter(), self.seconds) if playing else None
        self._stepped = time.perf_counter()
        self.shown_at = []

    def seek(self, index: int):
        """Show frame ``index`` (the slider, a step); playing goes on from there."""
        self.index = int(np.clip(index, 0, self.count - 1))
        if self.playing:
            self._clock = (time.perf_counter(), self.seconds)

    def tick(self):
        """While playing: the frame due now (with :attr:`every_frame`, the frame after the one shown, once
        it has been shown for its time); at the clip's end it stops there."""
        if not self.playing:
            return
        if self.every_frame:
            now = time.perf_counter()
            if self.on_screen >= self.frames.shown(self.index)[0]:
                if self.index >= self.count - 1:
                    self.playing, self._clock = False, None
                elif now - self._stepped >= self.times[self.index + 1] - self.times[self.index]:
                    self.index += 1
                    self._stepped = now
            return
        seconds = self._played()
        self.index = self.frame_at(seconds)
        if seconds >= self.times[-1] + 1.0 / self.fps:
            self.index = self.count - 1
            self.playing, self._clock = False, None

    def _played(self) -> float:
        """While playing by the clock: the clip's time due now."""
        start, at = self._clock
        return at + time.perf_counter() - start

    @property
    def rate(self) -> float | None:
        """Frames shown a second while playing (the last few seconds' worth), once two were."""
        t = self.shown_at[-30:]
        return (len(t) - 1) / (t[-1] - t[0]) if len(t) >= 2 and t[-1] > t[0] else None

    # ------------------------------------------------------------------ frames
    def _future(self, person: int) -> Future:
        """Frame ``person``'s read, started (reads asked before it and not begun are dropped: only the
        latest frame asked for is worth reading)."""
        if person not in self._loads:
            for other in [k for k, f in self._loads.items() if f.cancel()]:
                del self._loads[other]
            future = self._loads[person] = self._pool.submit(self.frames.scene, person, self.sizes)
            future.add_done_callback(lambda _: self.wake())
        return self._loads[person]

    def forget(self, index: int):
        """Frame ``index``'s read dropped (it failed: asked for again, it is read again)."""
        self._loads.pop(self.frames.shown(index)[1], None)

    def seconds_to_next(self) -> float | None:
        """While playing: seconds until the frame after the one asked for is due (None: paused)."""
        if not self.playing or self.index >= self.count - 1:
            return None if not self.playing else 0.0
        if self.every_frame:
            return max(self.times[self.index + 1] - self.times[self.index] - (time.perf_counter() - self._stepped), 0.0)
        return max(self.times[self.index + 1] - self._played(), 0.0)

    def _read_since(self, person: int) -> int | None:
        """The latest frame with a person after the one shown and at most ``person`` whose scene is read:
        what playing shows while the frame due is still being read (the clip goes on at the reads' pace)."""
        after = self.current[1] if self.current is not None else -1
        ready = [k for k, f in self._loads.items() if after < k <= person and f.done() and not f.cancelled() and f.exception() is None]
        return max(ready) if ready else None

    def scene(self, person: int, wait: bool = False):
        """Frame ``person``'s scene once read (``wait``: read now if need be), else None; the reads of
        other frames are dropped (at most the one asked and the one after are kept)."""
        future = self._future(person)
        if not (wait or future.done()):
            return None
        scene = future.result()  # a read that failed raises here: the window reports it
        for other in [k for k in self._loads if k != person]:
            if self._loads[other].done() or self._loads[other].cancel():
                del self._loads[other]
        return scene

    def advance(self, session, wait: bool = False) -> str | None:
        """Bring the frame asked for to the session: its person's scene (when read: the frame before stays
        meanwhile, unless ``wait``) and its camera's turn. Returns "person" when a new scene was given (a
        new person's frame is drawn whole before it shows), "turn" when only the turn changed, else None."""
        index, person = self.frames.shown(self.index)
        if self.current == (index, person):
            return None
        change = "turn"
        if self.current is None or self.current[1] != person:
            scene = self.scene(person, wait)
            if scene is None and self.playing and not self.every_frame and (ready := self._read_since(person)) is not None:
                index = person = ready
                scene = self.scene(person)
            if scene is None:
                return None
            session.set_scene(scene, self.frames.background_camera(person))
            change = "person"
        session.camera_turn, session.camera_height = self.frames.camera_turn(index, person), self.frames.camera_height(person)
        self.current = (index, person)
        if self.playing:
            self._read_ahead()
        return change

    @property
    def in_session(self) -> bool:
        """Whether the session has the frame asked for (its person's scene and its camera's turn)."""
        return self.current == self.frames.shown(self.index)

    def drew(self, index: int):
        """The window drew frame ``index``'s picture: the frame on screen (its rate counted while playing)."""
        if index != self.showing and self.playing:
            self.shown_at.append(time.perf_counter())
        self.showing = index

    def _read_ahead(self):
        """While playing: the scene of the frame likely due when this one has shown, read meanwhile."""
        rate = self.rate or 1.0
        ahead = self.frame_at(self.seconds + 1.0 / rate)
        _, person = self.frames.shown(ahead)
        if self.current is not None and person != self.current[1]:
            self._future(person)

    @property
    def has_person(self) -> bool:
        """Whether the frame shown has the person in it (else the new background alone shows)."""
        return self.current is not None and self.current[0] == self.current[1]

    def picture(self, engine) -> np.ndarray:
        """(H, W, 3) uint8: the session's frame as the relit MP4 shows it (:meth:`picture_of`)."""
        return self.picture_of(engine, *self.current)

    def picture_of(self, engine, index: int, person: int) -> np.ndarray:
        """(H, W, 3) uint8: frame ``index`` as the relit MP4 shows it, from ``engine`` (frame ``person``'s
        scene, rendered with the frame's turn): the relit frame, or with no person the new background
        alone (under the photo background the frame as filmed)."""
        if index == person:
            return engine.output.read_display()
        if shows_filmed_frame(engine):
            return self._filmed(index, engine.output_size)
        return engine.output.read_background_display()

    def _filmed(self, index: int, size: tuple[int, int]) -> np.ndarray:
        """Frame ``index`` as filmed, at ``size`` (kept while it is shown: a drag redraws it every frame)."""
        from viewer.output.clip_render import frame_photo

        key = (index, size)
        if self._filmed_frame is None or self._filmed_frame[0] != key:
            self._filmed_frame = (key, frame_photo(self.bundle, index, size))
        return self._filmed_frame[1]

    def picture_hdr(self, engine) -> np.ndarray:
        """(H, W, 3) float32: :meth:`picture`'s linear HDR (what a saved frame's EXR holds)."""
        from viewer.files.imageio import srgb_to_linear

        if self.has_person:
            return engine.output.read_output_hdr()[..., :3]
        if shows_filmed_frame(engine):
            return srgb_to_linear(self._filmed(self.current[0], engine.output_size) / 255.0).astype(np.float32)
        return engine.output.read_background_hdr()[..., :3]

    @property
    def own_texture(self):
        """The texture of the last frame drawn with no one in it (None before one was)."""
        return self._texture.texture

    def texture(self, engine, key: bytes):
        """What the window draws for the frame shown: ``engine``'s display, or for a frame without the
        person :meth:`picture` in a texture of the timeline's own (made again only when ``key``, the
        session's state, or the engine changes)."""
        if self.has_person:
            return engine.display
        # (the engine itself: an id can be another's once it is released)
        return self._texture.show((key, engine, self.current), lambda: self.picture(engine))

    @property
    def on_screen(self) -> int:
        """The frame the picture on screen is of (the frame asked for may still be coming, playing or not):
        what the slider and :meth:`describe` show."""
        return self.showing if self.showing is not None else self.index

    def describe(self) -> str:
        """The frame on screen, in words: its time, number and shot, and whether it has the person."""
        k = self.on_screen
        entry = self.bundle.frames[k]
        state = {"person": "", "no person": ", no one in it", "lost": ", lost (the frame before shows)"}[entry.state]
        return (f"{entry.seconds:.2f} / {self.bundle.duration:.2f} s, frame {k + 1} of {self.count}"
                + (f", shot {entry.shot + 1} of {self.shots}" if self.shots > 1 else "") + state)

    def release(self):
        self.wake = lambda: None  # a read still under way ends after the window
        self._texture.release()
        self._pool.shutdown(wait=False, cancel_futures=True)  # a read under way ends on its own (numpy, no GL)
