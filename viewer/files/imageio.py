"""Reading and writing files in standard formats: EXR (linear float), PNG (8/16-bit), HDR, and the
JSON the program reads (light files, bundles' scene.json, caches, cards, saved looks).

Every failure is an :class:`InputError` naming the file.
"""

from __future__ import annotations

import contextlib
import os
import threading
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.kinds import regular_file
from viewer.stop_signals import held

MARK = ("written_by", "relight")  # (key, value) inside every file this program writes (viewer.files.ownership)
MARK_TEXT = f"{MARK[0]}: {MARK[1]}"  # the mark where a format holds one text (a JPEG comment, an MP4's comment)


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; when the block ends without an exception it
    replaces ``path`` in one step (a reader never sees a half-written file, an interrupted write
    leaves the old file as it was). A failed write (a full disk) is an ``OSError`` naming ``path``,
    the file the user asked for, not its temporary name. (:func:`atomic_paths` of one file.)"""
    with atomic_paths(path) as (tmp,):
        yield tmp


@contextlib.contextmanager
def _named_as(path: Path, tmp: Path):
    """An ``OSError`` about ``tmp`` (or about no file: a stream's write) named as ``path``."""
    try:
        yield
    except OSError as exc:
        if exc.filename not in (None, str(tmp), os.fsencode(tmp)) or exc.errno is None:
            raise
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from None


@contextlib.contextmanager
def atomic_paths(*paths):
    """:func:`atomic_path` for files that go together (a frame's PNG and its EXR): a temporary path
    beside each; when the block ends without an exception all replace their files at once, with
    Ctrl-C, SIGTERM and SIGHUP held back until the last is in place (an interrupted write leaves all
    the old files or all the new ones, never a new PNG beside an old EXR)."""
    paths = [Path(p) for p in paths]
    for p in paths:
        p.parent.mkdir(parents=True, exist_ok=True)
    tmps = [p.with_name(f".{p.name}.{os.getpid()}.tmp") for p in paths]
    try:
        with contextlib.ExitStack() as naming:
            for p, tmp in zip(paths, tmps):
                naming.enter_context(_named_as(p, tmp))
            yield tmps
        # Python runs a signal's handler between any two bytecodes, even for a signal that arrived
        # before this point: the signals are held until every file is in place
        with held():
            for tmp, p in zip(tmps, paths):
                os.replace(tmp, p)
    finally:
        for tmp in tmps:
            if tmp.exists():
                tmp.unlink()


def ffmpeg_file(path) -> str:
    """``path`` as FFmpeg must be given a file: a ``file:`` URL of the absolute path, so a name with a
    colon (``v1:final.mp4``, ``turntable-12:30.mp4``) is a file, never read as a protocol."""
    return "file:" + os.fspath(Path(path).absolute())


MAX_JSON_BYTES = 64 << 20  # no JSON file this program reads is near this
MAX_IMAGE_PIXELS = 200_000_000  # every image format: larger is refused before decoding (decompression bombs)


def check_pixels(path, width: int, height: int, max_pixels: int = MAX_IMAGE_PIXELS) -> None:
    """Refuse a size read from a header, before any pixel is decoded: one rule and one message for
    every format (a header may claim anything)."""
    if width < 1 or height < 1 or width * height > max_pixels:
        raise InputError(path, f"is {width}x{height} pixels: more than the {max_pixels / 1e6:.3g} megapixels "
                               "this program reads (downsample it first)")


MAX_NUMBER_CHARS = 40  # a JSON number written with more characters is nothing this program reads


class _NumberOutOfRange(ValueError):
    pass


def _bounded_int(text: str) -> int:
    """An integer of the file (parsed with a bound: thousands of digits took Python's own limit, a
    ValueError, or overflowed into float)."""
    if len(text) > MAX_NUMBER_CHARS:
        raise _NumberOutOfRange(f"a number written with {len(text)} digits ({text[:12]}...): out of any range it reads")
    return int(text)


def _bounded_float(text: str) -> float:
    if len(text) > MAX_NUMBER_CHARS:
        raise _NumberOutOfRange(f"a number written with {len(text)} characters ({text[:12]}...): out of any range it reads")
    return float(text)


def read_json(path, what: str = "JSON file"):
    """The JSON value in ``path``: strict UTF-8, at most MAX_JSON_BYTES, any nesting the parser can
    take; anything else (missing, a folder, unreadable, wrongly encoded, malformed, absurdly deep
    or big) is one :class:`InputError` naming the file and ``what`` it should have been."""
    import json

    path = regular_file(path, what)  # missing, a folder, a pipe or a device: one line, nothing opened
    try:
        if path.stat().st_size > MAX_JSON_BYTES:
            raise InputError(path, f"is {path.stat().st_size >> 20} MB: too big for a {what}")
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(path, f"{what} not found") from None
    except IsADirectoryError:
        raise InputError(path, f"is a folder, not a {what}") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the {what} ({exc.strerror or exc})") from None
    try:
        return json.loads(data.decode("utf-8"), parse_int=_bounded_int, parse_float=_bounded_float)
    except _NumberOutOfRange as exc:
        raise InputError(path, f"not a {what}: {exc}") from None
    except UnicodeDecodeError as exc:
        raise InputError(path, f"not a {what}: byte {exc.start} is not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not a {what}: invalid JSON at line {exc.lineno} column {exc.colno} ({exc.msg})") from None
    except RecursionError:
        raise InputError(path, f"not a {what}: nested too deeply") from None


def write_text(path, text: str) -> Path:
    """Write a text file (JSON, Markdown) atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


# one block at a time: the descriptors and sys.stdout / sys.stderr are the process's, and two threads
# reading EXRs at once (a clip's frames read ahead beside the frame asked for) crossed them, the second
# to finish putting back the first's sink, closed: every later print failed and the window ended
_NATIVE_OUTPUT = threading.RLock()


@contextlib.contextmanager
def native_output():
    """Collect what native code and the bindings write to the process's stdout and stderr during the
    block (OpenEXR prints its own lines before it raises). Yields a list that holds the text after the block;
    the caller folds it into its one line on failure, or hands it back with :func:`replay` (another
    thread may have printed meanwhile)."""
    import ctypes
    import sys
    import tempfile

    libc = ctypes.CDLL(None)
    printed: list[str] = []
    with _NATIVE_OUTPUT:
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        libc.fflush(None)
        with tempfile.TemporaryFile() as sink:
            saved = [os.dup(1), os.dup(2)]
            # the bindings' own lines (pybind11's py::print) go to Python's sys.stdout, which the
            # program keeps on a private copy of descriptor 1 (cli.main): it is pointed at the sink too
            streams = sys.stdout, sys.stderr
            caught = open(os.dup(sink.fileno()), "w", encoding="utf-8", errors="replace", closefd=True)
            try:
                os.dup2(sink.fileno(), 1)
                os.dup2(sink.fileno(), 2)
                sys.stdout = sys.stderr = caught
                yield printed
            finally:
                sys.stdout, sys.stderr = streams
                caught.close()
                libc.fflush(None)  # C stdio's buffer (std::cout) to the sink before the descriptors go back
                for fd, old in zip((1, 2), saved):
                    os.dup2(old, fd)
                    os.close(old)
                sink.seek(0)
                printed.append(sink.read().decode("utf-8", "replace"))


def replay(printed: list[str]) -> None:
    """Print what :func:`native_output` collected, to stderr, as it would have appeared."""
    import sys

    if printed and printed[0]:
        sys.stderr.write(printed[0])
        sys.stderr.flush()


def _native_reason(exc: Exception, held: list[str]) -> str:
    """One reason from OpenEXR's exception and the lines it printed (its core's error line says
    most: the chunk, the offset), short enough for one line."""
    lines = [line.strip().removeprefix("<python_buffer>:").strip()
             for line in (held[0] if held else "").splitlines() if line.strip()]
    core = [line for line in lines if "EXR_ERR_" in line] or lines[-1:]
    said = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
    reason = f"{core[0]}; {said}" if core and core[0] not in said else said
    return reason if len(reason) <= 240 else reason[:237] + "..."


def read_exr(path, max_pixels: int = MAX_IMAGE_PIXELS) -> np.ndarray:
    """Float32 array, HxW for luminance (Y) or HxWxC for RGB / RGBA (luminance and chroma, Y RY BY,
    as RGB); any other channel set (alpha alone, depth) is one line naming the file. The file is opened once, by
    Python (any name the system takes, a byte name that is not UTF-8 included) and handed to
    OpenEXR as a stream; the data window is held to ``max_pixels`` (:func:`check_pixels`) before a pixel is
    read (a header may claim anything)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    try:
        stream = open(path, "rb")
    except OSError as exc:
        raise InputError(path, f"cannot read EXR ({exc.strerror or exc})") from None
    failure = None
    with stream, native_output() as printed, held():
        try:
            arr = _exr_pixels(stream, path, max_pixels)
        except InputError:
            raise
        except Exception as exc:  # OpenEXR raises plain exceptions for corrupt files
            failure = exc
    if failure is not None:
        raise InputError(path, f"cannot read EXR ({_native_reason(failure, printed)})")
    replay(printed)
    return arr


def _exr_pixels(stream, path: Path, max_pixels: int) -> np.ndarray:
    import OpenEXR

    with OpenEXR.File(stream, header_only=True) as f:
        lo, hi = (np.asarray(v, dtype=np.int64) for v in f.header()["dataWindow"])
    w, h = (int(v) for v in hi - lo + 1)
    check_pixels(path, w, h, max_pixels)
    stream.seek(0)
    with OpenEXR.File(stream) as f:
        channels = f.channels()
        for name in ("RGB", "RGBA"):
            if name in channels:
                return np.ascontiguousarray(channels[name].pixels, dtype=np.float32)
        if {"Y", "RY", "BY"} <= set(channels):
            return _from_luminance_chroma(*(channels[c].pixels for c in ("Y", "RY", "BY")))
        if "Y" in channels:
            return np.ascontiguousarray(channels["Y"].pixels, dtype=np.float32)
        raise InputError(path, f"holds the EXR channels {sorted(channels)[:8]}: no colour (R, G, B), luminance (Y) or "
                               "luminance and chroma (Y, RY, BY) to read")


REC709_LUMINANCE = (0.2126, 0.7152, 0.0722)  # OpenEXR's luminance weights for its default (Rec. 709) primaries


def _from_luminance_chroma(y: np.ndarray, ry: np.ndarray, by: np.ndarray) -> np.ndarray:
    """RGB of an EXR stored as luminance and chroma (OpenEXR's RgbaYca: RY = (R - Y) / Y, BY =
    (B - Y) / Y, chroma possibly at half resolution, brought to the luminance's)."""
    y = np.asarray(y, np.float32)

    def full(c):
        c = np.asarray(c, np.float32)
        if c.shape != y.shape:
            c = np.repeat(np.repeat(c, -(-y.shape[0] // c.shape[0]), axis=0), -(-y.shape[1] // c.shape[1]), axis=1)
            c = c[: y.shape[0], : y.shape[1]]
        return c

    wr, wg, wb = REC709_LUMINANCE
    r = (full(ry) + 1.0) * y
    b = (full(by) + 1.0) * y
    g = (y - wr * r - wb * b) / wg
    return np.ascontiguousarray(np.stack([r, g, b], axis=-1), dtype=np.float32)


def write_exr(path, arr: np.ndarray, half: bool = False) -> Path:
    """Write HxW (channel Y), HxWx3 (RGB) or HxWx4 (RGBA), ZIP-compressed, atomically. OpenEXR
    writes into a file Python opened: a full disk is the ``OSError`` it is (OpenEXR's own file
    raised a ``RuntimeError``), named as ``path``."""
    import OpenEXR

    path = Path(path)
    arr = np.asarray(arr)
    dtype = np.float16 if half else np.float32
    arr = np.ascontiguousarray(arr, dtype=dtype)
    name = {2: "Y", 3: {1: "Y", 3: "RGB", 4: "RGBA"}.get(arr.shape[-1])}[arr.ndim]
    if name is None:
        raise ValueError(f"cannot write an array of shape {arr.shape} as EXR")
    if arr.ndim == 3 and arr.shape[-1] == 1:
        arr = np.ascontiguousarray(arr[..., 0])
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, MARK[0]: MARK[1]}
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as stream, held():  # Python's file: any name, and a failed write is the OSError it is
            OpenEXR.File(header, {name: arr}).write(stream)
    return path


def read_png(path) -> np.ndarray:
    """Image as float32 in [0, 1] (8- or 16-bit PNG/JPEG), HxW or HxWxC; values as stored (no
    colour-space conversion)."""
    from PIL import Image

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    try:
        with Image.open(path) as im:
            im.load()
            if im.mode in ("I;16", "I;16B", "I"):
                arr = np.asarray(im, dtype=np.float32) / 65535.0
            else:
                if im.mode not in ("L", "RGB", "RGBA"):
                    im = im.convert("RGBA" if "A" in im.mode else "RGB")
                arr = np.asarray(im, dtype=np.float32) / 255.0
    except Exception as exc:
        raise InputError(path, f"cannot read image ({exc})") from None
    return arr


def write_png(path, arr: np.ndarray, bits: int = 8, compress_level: int = 6) -> Path:
    """Write values in [0, 1] (clipped) as an 8-bit PNG (grey, RGB or RGBA), or a 16-bit grey
    PNG (``bits=16``, for mattes)."""
    from PIL import Image

    path = Path(path)
    arr = np.asarray(arr, dtype=np.float32)
    if arr.ndim == 3 and arr.shape[-1] == 1:
        arr = arr[..., 0]
    if bits == 16:
        if arr.ndim != 2:
            raise ValueError("16-bit PNGs are written for one channel only")
        im = Image.fromarray((np.clip(np.nan_to_num(arr), 0.0, 1.0) * 65535.0 + 0.5).astype(np.uint16))
    else:
        im = Image.fromarray((np.clip(np.nan_to_num(arr), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8))
    with atomic_path(path) as tmp:
        im.save(tmp, format="PNG", compress_level=compress_level, pnginfo=png_mark())
    return path


def png_mark():
    """The PNG text chunk of :data:`MARK`, for every PNG this program writes."""
    from PIL import PngImagePlugin

    info = PngImagePlugin.PngInfo()
    info.add_text(*MARK)
    return info


def write_jpeg(path, arr: np.ndarray, quality: int = 90) -> Path:
    """Write RGB values in [0, 1] (clipped) as a JPEG (figures of photographs: a fifth of a PNG's size)."""
    from PIL import Image

    path = Path(path)
    im = Image.fromarray((np.clip(np.nan_to_num(np.asarray(arr, np.float32)), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8))
    with atomic_path(path) as tmp:
        im.save(tmp, format="JPEG", quality=quality, comment=MARK_TEXT)
    return path


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


SRGB_KNEE = 0.0031308  # linear values up to it are encoded by the straight segment (12.92 x), above it by the power law


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(np.asarray(x, dtype=np.float32), 0.0, None)
    return np.where(x <= SRGB_KNEE, x * 12.92, 1.055 * np.power(x, 1 / 2.4) - 0.055).astype(np.float32)
