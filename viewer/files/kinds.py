"""What a file the user gave is, so that a file of the wrong kind (a map given as a photo, a text file
given as a scene) is one line saying what it is and what to do with it, not "not found" or a
decoder's complaint. Decided by the name's suffix and, for JSON, the ``format`` field the program
writes; nothing is executed, and at most ``SNIFF_BYTES`` of a JSON file are read."""

from __future__ import annotations

import json
from pathlib import Path

from viewer.errors import InputError

PHOTO_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp", ".gif")
MAP_SUFFIXES = (".hdr", ".exr")
VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv", ".avi", ".webm")
TEXT_SUFFIXES = (".txt", ".md", ".rst", ".csv", ".py", ".toml", ".yaml", ".yml", ".log")
SNIFF_BYTES = 1 << 20
# the JSON files the program writes, by their "format" field
JSON_FORMATS = {"relight-rig": "rig", "relight-lights": "light file", "relight-scene": "scene description"}

# kind -> (what it is, in words; what to do with it)
KINDS = {
    "map": ("an environment map", "give it as --env: relight view --env {path}"),
    "rig": ("a rig of your lights", "give it as --rig: relight view --rig {path}"),
    "light file": ("a light file", "give it as the lights: relight render BUNDLE {path}"),
    "look": ("a saved look (a frame's settings)", "give it as --look: relight view BUNDLE --look {path}"),
    "scene description": ("a scene bundle's scene.json", "give its folder: relight view {parent}"),
    "video": ("a video", "the program reads photos, not videos: take a frame of it as a PNG"),
    "text": ("a text file", "give a photo (.png, .jpg), a scene bundle (a folder with scene.json) or, with "
                            "--env, a map (.hdr, .exr)"),
    "folder": ("a folder without scene.json, not a scene bundle", "make a bundle with relight infer PHOTO -o {path}"),
    "json": ("a JSON file the program did not write", "give a photo (.png, .jpg) or a scene bundle"),
}


def regular_file(path, what: str) -> Path:
    """``path`` when it is a regular file (links followed); else one line: not found, a folder, or a
    pipe, a socket or a device (``/dev/zero``, a FIFO, a shell's ``<(cat photo)``), refused before
    it is opened: opening a pipe nobody writes to blocks for ever, and a device never ends."""
    import stat

    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise InputError(path, f"{what} not found") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the {what} ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise InputError(path, f"is a folder, not a {what}")
    if not stat.S_ISREG(mode):
        raise InputError(path, f"is a pipe or a device, not a regular file: save the {what} to a file and give that")
    return path


def kind_of(path) -> str | None:
    """``photo``, ``bundle``, a key of :data:`KINDS`, or None (missing or not recognized)."""
    path = Path(path)
    if path.is_dir():
        return "bundle" if (path / "scene.json").is_file() else "folder"
    if not path.is_file():
        return None
    suffix = path.suffix.lower()
    if suffix in PHOTO_SUFFIXES:
        return "photo"
    if suffix in MAP_SUFFIXES:
        return "map"
    if suffix in VIDEO_SUFFIXES:
        return "video"
    if suffix in TEXT_SUFFIXES:
        return "text"
    if suffix == ".json":
        try:
            with open(path, "rb") as f:
                data = json.loads(f.read(SNIFF_BYTES))
        except (OSError, ValueError, RecursionError):
            return "json"
        if isinstance(data, dict):
            if data.get("format") in JSON_FORMATS:
                return JSON_FORMATS[data["format"]]
            if isinstance(data.get("look"), dict):
                return "look"
        return "json"
    return None


def wrong_kind(path, wanted: str) -> InputError | None:
    """The one-line error for ``path`` given where ``wanted`` (words: "a photo", "a photo or a scene
    bundle") was expected, when it is a file of another known kind; None when it is not."""
    kind = kind_of(path)
    if kind not in KINDS:
        return None
    what, todo = KINDS[kind]
    path = Path(path)
    return InputError(path, f"is {what}, not {wanted}: {todo.format(path=path, parent=path.parent)}")
