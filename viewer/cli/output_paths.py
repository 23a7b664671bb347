"""Where a command may write: checked before any work (writable, not an input, a name that fits
with its temporary suffix), and the video options that must hold before a frame is drawn."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from viewer.errors import InputError


def beside_the_map(map_path: Path) -> Path | None:
    """``MAP.lights.json`` beside the map (what the viewer reads for that map) when its folder is
    writable, else None (the lights then stay in the fitting cache)."""
    folder = map_path.parent
    from viewer.lighting.map_lights import lights_beside

    return lights_beside(map_path) if os.access(folder, os.W_OK | os.X_OK) else None


def writable(path, folder: bool = False) -> Path:
    """``path`` if the program can write it, checked before any work is done: else one line naming
    it. ``folder``: the path is itself a folder to write into. Missing folders are made only when
    the output is written, so a command that fails leaves none behind: here the nearest existing
    folder above must be one the program may create them in."""
    path = Path(path)
    where = path if folder else path.parent
    if not folder and path.is_dir():
        raise InputError(path, "is a folder: give a file path")
    existing = where.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(path, f"cannot write here ({existing} is a file, not a folder)")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(path, f"cannot write here ({existing} is not writable)")
    if existing != where.absolute():  # folders to make: a folder made and taken away again proves it can be done
        import tempfile

        try:
            os.rmdir(tempfile.mkdtemp(prefix=".relight-probe-", dir=existing))
        except OSError as exc:
            raise InputError(path, f"cannot write here ({exc.strerror or exc})") from None
    return path


NAME_MAX = 255 - 24  # bytes of a file name, leaving room for the temporary name it is written under


def not_an_input(outputs, inputs, folders=()):
    """Refuse outputs that would replace an input (a map, a light file, a photo) or land inside an
    input folder (a scene bundle): the user's files are never written over. ``folders``: outputs that
    are folders (a relit clip's parts and layers; whether one there is this program's is the
    writer's to check)."""
    folders = [Path(f) for f in folders]
    for out in list(outputs) + folders:
        out = Path(out)
        if len(os.fsencode(out.name)) > NAME_MAX:
            raise InputError(out, f"the file name is longer than {NAME_MAX} bytes")
        try:
            str(out).encode("utf-8")
        except UnicodeEncodeError:  # a byte that is not UTF-8, kept by Python as a surrogate
            raise InputError(out, "the path is not valid UTF-8 (the image and video writers take UTF-8 "
                                  "names): choose a UTF-8 name") from None
        if not out.name.isprintable():
            raise InputError(out, "the file name holds control characters (a newline?)")
        resolved = out.resolve()
        for given in inputs:
            if given is None:
                continue
            src = Path(given).resolve()
            if resolved == src or (src.is_dir() and src in resolved.parents):
                raise InputError(out, f"would write over the input {given}: give another output path")
        if out.is_dir() and out not in folders:
            raise InputError(out, "is a folder: the output would replace it")


MAX_FRAMES = 100_000  # an hour at 30 fps
FPS_RANGE = (0.1, 1000.0)


def check_video(args):
    """--frames, --fps and --turn within what a video can be, named when not."""
    if args.frames is not None and not 1 <= args.frames <= MAX_FRAMES:
        raise InputError(None, f"--frames must be in [1, {MAX_FRAMES}], got {args.frames}")
    check_fps(args)
    if args.turn is not None and not (np.isfinite(args.turn) and abs(args.turn) <= 36000):
        raise InputError(None, f"--turn must be a finite number of degrees within +-36000, got {args.turn}")


CLIP_FLAGS = ("temporal", "person", "people")  # besides --start and --end, what only a clip's inference takes
INFERRED_ONLY = "--start, --end, --temporal, --person and --people"


def inferred_only(args) -> bool:
    """Whether ``args`` set an option that only a clip's inference takes (:data:`INFERRED_ONLY`)."""
    return getattr(args, "start", 0.0) != 0.0 or getattr(args, "end", None) is not None or \
        any(getattr(args, k, None) is not None for k in CLIP_FLAGS)


def not_a_clip_range(args, given) -> None:
    """Refuse --start / --end for what is not a clip (they would be silently ignored)."""
    if getattr(args, "start", 0.0) != 0.0 or getattr(args, "end", None) is not None:
        raise InputError(given, "--start and --end choose a part of a clip: this is not one")
    for flag in CLIP_FLAGS:
        if getattr(args, flag, None) is not None:
            raise InputError(given, f"--{flag} is for a clip: this is not one")


def check_fps(args):
    """--fps within what a video (or the viewer's recording) can be, named when not."""
    if not (np.isfinite(args.fps) and FPS_RANGE[0] <= args.fps <= FPS_RANGE[1]):
        raise InputError(None, f"--fps must be in [{FPS_RANGE[0]:g}, {FPS_RANGE[1]:g}], got {args.fps}")
