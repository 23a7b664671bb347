"""A clip bundle relit into an MP4: the source's frames, timing and audio, under a new light.

Every output frame is a function of its index alone (:class:`ClipPictures`): a frame with a
person is its scene bundle rendered under the look (the map turned by ``turn`` degrees over the
clip, in proportion to the frame's time; the automatic exposure resolved once per shot on its first
frame with a person, or, for a clip inferred frame by frame, each frame's own, as a photo's); a
frame where no person was found shows the new background alone (as the nearest frame with a
person sees it, with no person and no shadow), or the frame itself under ``--background photo``;
a frame lost to a damaged packet shows the frame before it. So a run that stops and starts again
renders exactly what an unbroken run does.

The video is written in parts of ``PART_SECONDS`` (``<name>.parts/`` beside the output, each
part written whole or not at all) and joined at the end with the source's audio
(:func:`viewer.output.video.join_clip`); a run that stops keeps its finished parts, and the same
command goes on from there. The parts are removed once the video is in place.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import re
import shutil
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import MARK, read_png, write_png, write_text
from viewer.files.ownership import file_is_ours, file_sha256, take_away
from viewer.memory_needs import frames_freed
from viewer.output.clip_frames import ClipFrames, shows_filmed_frame
from viewer.output.render import render_look, warn_if_unseen
from viewer.output.video import VideoWriter, encoded_size, join_clip
from viewer.scene.area_lights import AreaLights
from viewer.scene.clip_bundle import FRAMES, ClipBundle, frame_name
from viewer.scene.look import AUTO, Look

PART_SECONDS = 2.0  # of the clip in each part: what a stopped run may have to render again
PARTS_RECORD = "parts.json"


class ClipPictures:
    """The relit clip's frames by index (:meth:`picture`), rendered on ``ctx`` with one engine at a
    time (the last frame's, kept while frames with no person reuse it)."""

    def __init__(self, ctx, bundle: ClipBundle, lights: AreaLights, look: Look, environment: np.ndarray | None,
                 fixed: AreaLights | None, options, turn: float = 0.0, sizes: tuple = (None, None)):
        self.ctx, self.bundle, self.lights, self.look, self.sizes = ctx, bundle, lights, look, sizes
        self.environment, self.fixed, self.options, self.turn = environment, fixed, options, turn
        self.frames = ClipFrames(bundle)
        self._engine = None  # (frame index, Engine, Scene)
        self._rendered = None  # (the look asked, the look resolved): what the engine holds rendered now
        self._exposures: dict[int, float] = {}  # shot -> its exposure (a clip inferred as one)
        self._warned = False
        # each frame's size, and the pictures' (a plate's frames are the plate's: viewer.output.plate_clip)
        self.size = self.frame_size = self.frames.scene(self.frames.people[0], sizes).output_size

    def frame_look(self, index: int, person: int) -> Look:
        """The look frame ``index`` renders with (:meth:`Look.on_frame`): the map turned ``turn`` degrees
        over the clip, tilted as the shot's camera looks up or down and turned as the camera turned
        since its shot began, its ground seen from the camera's height (``person``: the frame whose
        background camera is used, :meth:`ClipFrames.camera_turn`)."""
        yaw, tilt = self.frames.camera_turn(index, person)
        turn = self.turn * self.bundle.frames[index].seconds / self.bundle.duration + yaw
        return self.look.on_frame((turn, tilt), self.frames.camera_height(person))

    def _look(self, index: int, person: int) -> Look:
        """The look of frame ``index`` (:meth:`frame_look`); in a clip inferred as one (temporal), the
        exposure of the shot of frame ``person`` (a person's), resolved once on that shot's first frame
        with a person."""
        look = self.frame_look(index, person)
        if self.look.exposure != AUTO or not self.bundle.temporal:
            return look
        shot = self.bundle.frames[person].shot
        if shot not in self._exposures:
            first = self.frames.shot_start(shot)
            self._exposures[shot] = self._render(first, self.frame_look(first, first))[1].exposure
        return replace(look, exposure=self._exposures[shot])

    def _render(self, index: int, look: Look):
        """Frame ``index`` (a person's) rendered with ``look``: (its engine after the render, the look
        with its exposure resolved)."""
        from viewer.gl import Engine

        if self._engine is None or self._engine[0] != index:
            self.release()
            scene = self.frames.scene(index, self.sizes)
            if scene.output_size != self.frame_size:
                raise InputError(self.bundle.scene_path(index), f"its frame is {scene.output_size[0]}x{scene.output_size[1]}, "
                                                                f"the clip's {self.frame_size[0]}x{self.frame_size[1]}")
            self._engine = (index, Engine(self.ctx, scene, self.options, self.frames.background_camera(index)), scene)
        _, engine, scene = self._engine
        if self._rendered is None or self._rendered[0] != look:  # (a frame's layers after its picture: rendered once)
            self._rendered = (look, render_look(engine, scene, self.lights, look, self.environment, self.fixed)[0])
        settings = self._rendered[1]
        if not self._warned:
            warn_if_unseen(engine, scene, settings, True)
            self._warned = True
        return engine, settings

    def follow(self, bundle: ClipBundle) -> None:
        """The same clip with more of its frames inferred (``bundle``, a relit clip that follows its
        inference): what was resolved from the frames before is kept (each is final)."""
        if bundle is not self.bundle:
            self.bundle, self.frames = bundle, self.frames.grown(bundle)

    def key(self) -> str:
        """What these frames are made from beyond :func:`render_key`'s (a plate's: :mod:`viewer.output.plate_clip`)."""
        return ""

    def picture(self, index: int) -> np.ndarray:
        """(H, W, 3) uint8: output frame ``index``."""
        index, person = self.frames.shown(index)
        if person == index:
            return self._render(index, self._look(index, index))[0].output.read_display()
        engine = self._render(person, self._look(index, person))[0]
        if shows_filmed_frame(engine):  # the frame itself: there is no one in it to relight
            return frame_photo(self.bundle, index, self.frame_size)
        return engine.output.read_background_display()

    def person_hdr(self, index: int) -> np.ndarray | None:
        """(H, W, 4) float32: output frame ``index``'s person, linear RGB before the exposure,
        premultiplied by their coverage (A), as :meth:`picture` shows them; None for a frame without them."""
        index, person = self.frames.shown(index)
        if person != index:
            return None
        hdr = self._render(index, self._look(index, index))[0].output.read_hdr_rgba()
        hdr[..., :3] *= hdr[..., 3:]
        return hdr

    def layers(self, index: int, per_light: bool = False) -> dict[str, np.ndarray]:
        """The layers of output frame ``index`` (:mod:`viewer.output.layers`), as :meth:`picture` shows it."""
        from viewer.output.layers import background_channels, layer_channels

        index, person = self.frames.shown(index)
        if person == index:
            engine, _ = self._render(index, self._look(index, index))
            channels = layer_channels(engine, self._engine[2], per_light)
            self._rendered = None  # (the layers rendered it unshadowed too)
            return channels
        engine = self._render(person, self._look(index, person))[0]
        channels = background_channels(engine, per_light)
        if shows_filmed_frame(engine):  # the frame itself, as the picture shows it
            from viewer.files.imageio import srgb_to_linear

            photo = srgb_to_linear(frame_photo(self.bundle, index, self.frame_size) / 255.0)
            channels.update({c: np.ascontiguousarray(photo[..., i], np.float32) for i, c in enumerate("RGB")})
        return channels

    def release(self):
        if self._engine is not None:
            self._engine[1].release()
            self._engine = None
        self._rendered = None


class Part(NamedTuple):
    """Part ``index`` of a relit clip: frames ``first`` to ``last`` (excluded), written as :attr:`name`
    in the parts folder."""

    index: int
    first: int
    last: int

    @property
    def name(self) -> str:
        return f"{self.index:06d}.mp4"


def part_frames(bundle: ClipBundle) -> int:
    """The frames in each part but the last: ``PART_SECONDS`` of the clip."""
    return max(int(round(PART_SECONDS * float(bundle.source.get("fps") or 30.0))), 1)


def clip_parts(bundle: ClipBundle) -> list[Part]:
    """The parts a relit ``bundle`` is written in: ``PART_SECONDS`` of the clip each."""
    per, count = part_frames(bundle), len(bundle.frames)
    return [Part(k, first, min(first + per, count)) for k, first in enumerate(range(0, count, per))]


def _following_parts(bundle: ClipBundle, follow):
    """The parts of a clip still being inferred, each as its first frame is (``follow``, :func:`render_clip`'s),
    ``PART_SECONDS`` long until the inference ends (the last part's frames are then cut to the clip's)."""
    per = part_frames(bundle)
    for k in itertools.count():
        if k * per >= len(follow(k * per).frames):  # (a bundle shorter than that is the whole clip)
            return
        yield Part(k, k * per, (k + 1) * per)


def join_relit(bundle: ClipBundle, parts: list[tuple[Path, float]], path, duration: float | None = None) -> str | None:
    """The relit ``parts`` of ``bundle``'s clip joined into the MP4 ``path`` with the source's audio
    for ``duration`` seconds (default: the clip's) (:func:`viewer.output.video.join_clip`), when the
    source clip is still there as it was; returns a note for the user when the audio could not come
    (or went into a sidecar)."""
    audio, note = None, None
    if bundle.source.get("audio"):
        source = Path(bundle.source["path"])
        if source.is_file() and file_sha256(source) == bundle.source.get("sha256"):
            audio = source
        else:
            note = f"the source clip {source} is not there as it was: the relit clip has no audio"
    return join_clip(parts, path, audio, float(bundle.record.get("first_frame_at", 0.0)),
                     bundle.duration if duration is None else duration) or note


def frame_photo(bundle: ClipBundle, index: int, size: tuple[int, int]) -> np.ndarray:
    """(H, W, 3) uint8: frame ``index`` of the clip as it was filmed, at ``size``: what a frame with no
    one in it shows under ``--background photo``."""
    from viewer.resize import resize

    photo = read_png(bundle.path / FRAMES / f"{frame_name(index)}.png")[..., :3]
    return resize((photo * 255.0 + 0.5).astype(np.uint8), size)


def render_key(bundle: ClipBundle, lights: AreaLights, look: Look, environment, fixed, options, turn: float, sizes: tuple) -> str:
    """What a relit clip is made from, hashed: a part made under another key is not reused."""
    h = hashlib.sha256(json.dumps({"bundle": bundle.record.get("key"), "lights": lights.to_json(), "look": look.to_json(),
                                   "fixed": fixed.to_json() if fixed is not None else None, "options": repr(options),
                                   "turn": turn, "sizes": sizes}, sort_keys=True, default=str).encode())
    if environment is not None:
        h.update(np.ascontiguousarray(environment).tobytes())
    return h.hexdigest()


def parts_folder(path) -> Path:
    path = Path(path)
    return path.with_name(f"{path.stem}.parts")


def _same_key(record: Path, key: str) -> bool:
    try:
        return json.loads(record.read_text()).get("key") == key
    except (OSError, ValueError):
        return False


def _keyed(folder: Path, record: str, key: str) -> Path:
    """``folder`` (checked to be this program's) for the render ``key``: taken away when its ``record``
    holds another key, made with the record when it is not there."""
    if folder.exists() and not _same_key(folder / record, key):
        take_away(folder)
    if not folder.exists():
        from viewer.stop_signals import held

        with held():  # the folder and its record made together: a stop between them left a folder no run could take
            folder.mkdir(parents=True)
            write_text(folder / record, json.dumps({"key": key, MARK[0]: MARK[1]}) + "\n")
    return folder


def _open_parts(path: Path, key: str) -> Path:
    """The parts folder of ``path``, kept when it holds parts of the same render, else made anew.
    A folder of that name that relit did not write is refused in one line."""
    folder = parts_folder(path)
    if folder.exists():
        if not file_is_ours(folder / PARTS_RECORD) or any(not (p.name == PARTS_RECORD or p.name.endswith(".partial.mp4") or file_is_ours(p))
                                           for p in folder.iterdir()):
            raise InputError(folder, "is not a folder of relit parts relight wrote: move it away or choose another -o")
    _keyed(folder, PARTS_RECORD, key)
    for p in folder.glob("*.partial.mp4"):  # a part cut short by a stopped run: made again
        p.unlink()
    return folder


def layers_folder(path) -> Path:
    """Where a relit clip's layers go: ``NAME.layers/`` beside ``NAME.mp4``, an EXR per frame."""
    path = Path(path)
    return path.with_name(f"{path.stem}.layers")


LAYERS_RECORD = "layers.json"
LAYER_CHANNELS = 25  # of a frame's layers EXR, and 3 a light with --per-light (viewer.output.layers)
LAYER_CHANNEL_BYTES = 0.6 * 4  # a float32 channel's bytes a pixel, ZIP-compressed (measured 0.55-0.6 of them)
LEFTOVER = re.compile(r"^\.(\d{6}\.exr|layers\.json)\.\d+\.tmp$")  # a write a killed run left (viewer.files.imageio.atomic_path)


def layer_name(index: int) -> str:
    return f"{index:06d}.exr"


def check_layers_folder(path) -> Path:
    """The layers folder of ``path``, refused in one line when it is there and holds anything relight
    did not write (the command checks it before the inference)."""
    folder = layers_folder(path)
    if not folder.exists():
        return folder
    names = [p for p in folder.iterdir() if not LEFTOVER.match(p.name)]
    if names and (not file_is_ours(folder / LAYERS_RECORD) or any(not file_is_ours(p) for p in names)):
        raise InputError(folder, "is not a folder of layers relight wrote: move it away or choose another -o")
    return folder


def layer_lights(lights: AreaLights, fixed: AreaLights | None, per_light: bool) -> int:
    """The lights a frame's layers have a layer each for (``per_light``: every light, the map's and the placed)."""
    return len(lights) + (len(fixed) if fixed is not None else 0) if per_light else 0


def layers_bytes(frames: int, size: tuple[int, int], lights: int = 0) -> float:
    """About what ``frames`` frames of layers take on the disk at ``size``, with ``lights`` per-light layers."""
    return LAYER_CHANNEL_BYTES * (LAYER_CHANNELS + 3 * lights) * size[0] * size[1] * frames


def check_layers_room(path, frames: int, size: tuple[int, int], lights: int) -> None:
    """Refuse, in one line, layers of ``frames`` frames at ``size`` that the disk cannot hold (those of
    the same render already in the folder counted as there)."""
    folder = layers_folder(path)
    done = sum(1 for _ in folder.glob("*.exr")) if folder.is_dir() else 0
    need = layers_bytes(max(frames - done, 0), size, lights)
    free = shutil.disk_usage(folder if folder.is_dir() else folder.parent).free
    if need > free:
        raise InputError(folder, f"{frames} frames of layers at {size[0]}x{size[1]} would need about {need / 1e9:.1f} GB of disk, "
                                 f"{free / 1e9:.1f} GB is free: choose a part with --start and --end, or a smaller --max-size")


def _open_layers(path: Path, key: str, frames: int, size: tuple[int, int], lights: int) -> Path:
    """The layers folder of ``path``: kept when it holds layers of the same render (their frames are
    not made again), else made anew; a folder of that name holding anything relight did not write is
    refused in one line, as is a sequence the disk cannot hold (``lights``: per-light layers)."""
    folder = check_layers_folder(path)
    if folder.exists():
        for p in folder.iterdir():  # writes a killed run left
            if LEFTOVER.match(p.name):
                p.unlink()
        if not _same_key(folder / LAYERS_RECORD, key):
            take_away(folder)
    check_layers_room(path, frames, size, lights)
    return _keyed(folder, LAYERS_RECORD, key)


def _folders(pictures: ClipPictures, path: Path, layers: bool, per_light: bool, ready: bool = False) -> tuple[Path, Path | None]:
    """(the parts folder, the layers folder or None) of ``pictures`` relit into ``path``: made ready for
    this render (kept when they hold its parts and layers, else made anew), or, ``ready``, checked to
    be so (a worker's share: the folders are its driver's)."""
    p = pictures
    key = render_key(p.bundle, p.lights, p.look, p.environment, p.fixed, p.options, p.turn, p.sizes) + p.key()
    layers_key = f"{key} {per_light}"
    if not ready:
        sequence = _open_layers(path, layers_key, len(p.bundle.frames), p.size, layer_lights(p.lights, p.fixed, per_light)) \
            if layers else None
        return _open_parts(path, key), sequence
    folder, sequence = parts_folder(path), layers_folder(path) if layers else None
    for record, held in ((folder / PARTS_RECORD, key), (sequence / LAYERS_RECORD if sequence else None, layers_key)):
        if record is not None and not _same_key(record, held):
            raise InputError(record.parent, "is not ready for this render (made again by another run?): run again")
    return folder, sequence


def open_render(pictures: ClipPictures, path, layers: bool = False, per_light: bool = False) -> list[Part]:
    """What :func:`render_clip` does first, alone: the folders made ready for this render; returns the
    parts not made yet (a batch hands them to its workers, ``render_clip(only=...)``, before the item's
    own render joins them)."""
    bundle = pictures.bundle
    try:
        folder, _ = _folders(pictures, Path(path), layers, per_light)
    finally:
        pictures.release()
    return [p for p in clip_parts(bundle) if not file_is_ours(folder / p.name)]


def render_clip(pictures: ClipPictures, path, progress=None, poster=None, layers: bool = False, per_light: bool = False,
                share=None, only: list[int] | None = None, follow=None) -> dict:
    """Relight ``pictures``' clip bundle (:class:`ClipPictures`: the bundle, its lights, look, map and
    engine options, the map's turn over the clip, the sizes each frame's scene is loaded with; a clip
    on a plate, :class:`viewer.output.plate_clip.PlatePictures`) into the MP4 ``path``;
    ``progress(done, total)`` after every frame (parts kept from an earlier run count at once). Returns
    what was done: frames, size, parts reused, the audio's note. ``poster``: a PNG path for the clip's
    middle frame, relit (a batch's contact sheet shows it); ``layers``: also each frame's layers
    (:mod:`viewer.output.layers`, ``per_light``: each light's too) as ``NAME.layers/NNNNNN.exr`` (the
    frame's index), kept beside the video.

    Spread over workers (``relight render CLIP --ray``, :mod:`viewer.batch.spread_clip`): ``share(parts)``
    is handed the parts not made yet (:class:`Part` each) once the folders are ready, and returns when
    the workers have made them; each worker makes its own with ``only`` (the parts' numbers: the folders
    are the caller's, opened and checked by it, and nothing is joined: returns the parts made). Every frame
    is a function of its index alone, so the parts join without a seam.

    Following the clip's inference (``relight render CLIP``: the relighting on one core while the
    inference takes the other, :mod:`viewer.photo.clip_follow`): ``bundle`` holds the frames inferred
    so far, and ``follow(i)`` returns the bundle once frame ``i`` is final (inferred, and the frame with
    a person it shows known), or the whole bundle once the inference has ended; each frame is then
    what the whole bundle would make of it."""
    from viewer.output.layers import write_layers

    bundle, look = pictures.bundle, pictures.look
    if follow is not None and (share is not None or only is not None or pictures.turn):
        raise ValueError("a relighting that follows the inference is one process's (no share, no only), "
                         "its map turned by no clip length (no turn)")
    path = Path(path)
    folder, sequence = _folders(pictures, path, layers, per_light, ready=only is not None)

    def frame_layers(i: int) -> None:  # frame i's layers, unless the same render's are there
        if sequence is not None and not file_is_ours(sequence / layer_name(i)):
            write_layers(sequence / layer_name(i), pictures.layers(i, per_light))

    def frames_of(piece: Part):  # the part's frames, each once it is final
        for i in range(piece.first, piece.last):
            if follow is not None:
                now = follow(i)
                if i >= len(now.frames):  # the inference has ended: the clip is shorter
                    return
                pictures.follow(now)
            yield i

    def total() -> int:  # the frames to relight (following: the inference's estimate until it ends)
        return max(follow.total, len(pictures.bundle.frames)) if follow is not None else len(bundle.frames)

    fps = float(bundle.source.get("fps") or 30.0)
    shared = [p for p in clip_parts(bundle) if not file_is_ours(folder / p.name)] if share is not None else []
    if shared:
        share(shared)
    parts, reused = [], 0
    with frames_freed() as after_frame:
        try:
            for piece in clip_parts(bundle) if follow is None else _following_parts(bundle, follow):
                if only is not None and piece.index not in only:
                    continue
                part = folder / piece.name
                if file_is_ours(part):  # finished by an earlier run of the same render, or by a worker just now
                    reused += piece not in shared
                    for i in frames_of(piece):  # its layers, where a stop left them out
                        frame_layers(i)
                else:
                    with VideoWriter(part, *pictures.size, fps=fps) as video:
                        for i in frames_of(piece):
                            picture = pictures.picture(i)
                            video.write(picture, seconds=pictures.bundle.frames[i].seconds)
                            after_frame()
                            if poster is not None and follow is None and i == len(bundle.frames) // 2:
                                write_png(poster, picture / 255.0)
                                poster = None
                            frame_layers(i)
                            if progress is not None:
                                progress(i + 1, total())
                if progress is not None:
                    progress(min(piece.last, len(pictures.bundle.frames)), total())
                parts.append((part, pictures.bundle.frames[piece.first].seconds))
            bundle = pictures.bundle if follow is None else follow(len(pictures.bundle.frames))  # (following: the whole clip)
            if poster is not None:  # its part was kept from an earlier run (or the middle was known only at the end): made again
                write_png(poster, pictures.picture(len(bundle.frames) // 2) / 255.0)
        finally:
            pictures.release()
    if only is not None:
        return {"parts": [p.name for p, _ in parts], "reused": reused}
    note = join_relit(bundle, parts, path)
    take_away(folder)
    first = pictures.frames.people[0]
    pitch, how = pictures.frames.pitch(first)
    height = pictures.frames.camera_height(first)
    return {"frames": len(bundle.frames), "size": encoded_size(pictures.size), "parts_reused": reused, "audio_note": note,
            "layers": sequence, "pitch": f"the clip's horizon ({how}): the new map's horizon put there"
            + (f" (the map tilted {pitch:.1f} degrees)" if pitch else "")
            + (f"; the camera {height:.1f} m above the ground (from the person's height in the frame): the map's ground"
               " seen from there" if height and not look.camera_height and look.background == "environment" else "")}
