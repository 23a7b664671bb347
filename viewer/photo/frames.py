"""A photo as the user gave it: read upright, and the three frames the pipeline works in.

- the **photo** itself: its pixels after the EXIF orientation is applied (a phone's sideways JPEG
  comes out upright, with a note);
- the **frame**: the photo scaled so that its longer side is at most ``max_size`` (default
  ``MAX_SIZE``), same aspect. Every output (PNG, EXR, video, the viewer's saved frames) is this
  size; nothing is padded;
- the **work frame**: the same field of view at a lower resolution, where the person's longer
  side spans about ``work_person`` pixels (``WORK_PERSON``). The scene bundle's maps, the shadow
  maps and the per-light shading live here; the final composite brings them to the frame.

The three frames share one camera (a lens on a sensor spanning the longer side, principal point in
the middle), so a pixel (x, y) of the frame is the point (x s, y s) of the work frame with
``s = work / frame`` for either axis.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from viewer.errors import InputError, NoPersonError
from viewer.files.imageio import MAX_IMAGE_PIXELS, check_pixels
from viewer.files.kinds import regular_file, wrong_kind
from viewer.resize import scaled_size

MAX_SIZE = 2048  # default longer side of every output
WORK_PERSON = 512  # default pixels of the person's longer side in the work frame
MAX_PIXELS = MAX_IMAGE_PIXELS  # larger photos are refused (decompression bombs), as every image
MIN_PERSON_PX = 32
MIN_FRAME = 64  # --max-size below this leaves no room for a person of MIN_PERSON_PX
MAX_WORK = 4096  # the work frame's longer side at most (its float targets grow with its square)


@dataclass(frozen=True)
class FrameSizes:
    """Sizes (width, height) of the photo, the output frame and the work frame."""

    photo: tuple[int, int]
    frame: tuple[int, int]
    work: tuple[int, int]

    @property
    def work_scale(self) -> float:
        """Work pixels per frame pixel."""
        return max(self.work) / max(self.frame)

    def to_json(self) -> dict:
        return {"photo": list(self.photo), "frame": list(self.frame), "work": list(self.work)}


def output_frame(photo_size: tuple[int, int], max_size: int = MAX_SIZE) -> tuple[int, int]:
    """The output frame (width, height): the photo's own size, its longer side capped at ``max_size``."""
    if not MIN_FRAME <= max_size <= 16384:
        raise InputError(None, f"--max-size must be within [{MIN_FRAME}, 16384] pixels, got {max_size}")
    return tuple(photo_size) if max(photo_size) <= max_size else scaled_size(photo_size, max_size)


def frame_sizes(photo_size: tuple[int, int], person_box: tuple[int, int], max_size: int = MAX_SIZE,
                work_person: int = WORK_PERSON) -> FrameSizes:
    """The frame (photo capped at ``max_size``) and the work frame (person's longer side about
    ``work_person`` pixels, never larger than the frame nor than ``MAX_WORK``) of a photo whose
    person's bounding box is ``person_box`` = (width, height) photo pixels."""
    if not MIN_PERSON_PX <= work_person <= MAX_WORK:
        raise InputError(None, f"the work size must be within [{MIN_PERSON_PX}, {MAX_WORK}] pixels, got {work_person}")
    frame = output_frame(photo_size, max_size)
    person = max(person_box) * max(frame) / max(photo_size)
    work_long = min(max(frame), MAX_WORK, int(round(max(frame) * work_person / max(person, 1.0))))
    work = frame if work_long >= max(frame) else scaled_size(frame, work_long)
    return FrameSizes(tuple(photo_size), tuple(frame), tuple(work))


def exif_focal_35(exif) -> float | None:
    """The 35-mm-equivalent focal length (mm) an EXIF block (Pillow's ``Image.Exif``) gives (tag 0xA405,
    which phones and most cameras write), or None."""
    sub = exif.get_ifd(0x8769) if exif else {}
    value = sub.get(0xA405) or (exif.get(0xA405) if exif else None)
    try:
        value = float(value) if value else None
    except (TypeError, ValueError):
        value = None
    return value if value and 4.0 <= value <= 2000.0 else None


def read_image_u8(path, what: str, notes: list, digests: dict | None = None, colours: bool = True,
                  lens: dict | None = None, max_pixels: int = MAX_PIXELS) -> np.ndarray:
    """An image file as uint8 (H, W[, C]), upright: the EXIF orientation applied (with a note),
    16-bit images reduced to 8 bits (with a note), palette and other modes converted, colours in an
    embedded ICC profile other than sRGB (Adobe RGB, Display P3, ProPhoto) converted to sRGB by
    LittleCMS (Pillow's ImageCms; with a note; ``colours`` False: values, not colours, as a mask's,
    never converted). The file is read once: ``digests[what]`` (when given)
    is the SHA-256 of the very bytes decoded (a file replaced meanwhile cannot pass for another), and
    ``lens["focal_35mm"]`` (when given) its EXIF's 35-mm-equivalent focal length, or None. Larger than
    ``max_pixels`` is refused from its header, before any pixel is decoded; an animated image (a GIF, an APNG) is
    read as its first frame, with a note."""
    import hashlib
    import io

    from PIL import Image, ImageOps

    path = regular_file(path, what)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(path, f"cannot read the {what} ({exc.strerror or exc})") from None
    if digests is not None:
        digests[what] = hashlib.sha256(data).hexdigest()
    try:
        with open_image_header(io.BytesIO(data)) as im:
            check_pixels(path, im.width, im.height, min(max_pixels, MAX_PIXELS))  # Pillow itself only refuses twice its limit
            frames = getattr(im, "n_frames", 1)
            if isinstance(frames, int) and frames > 1:
                notes.append(f"the {what} is animated ({frames} frames): its first frame is used (a clip is read as a video: "
                             "convert it to MP4)")
            exif = im.getexif()
            orientation = exif.get(0x0112, 1)
            if lens is not None:
                try:
                    lens["focal_35mm"] = exif_focal_35(exif)
                except Exception:  # a broken EXIF block is no focal length: the pixels are what matters
                    lens["focal_35mm"] = None
            icc = im.info.get("icc_profile")
            upright = ImageOps.exif_transpose(im)
            upright.load()
            if orientation not in (1, None) and isinstance(orientation, int) and 2 <= orientation <= 8:
                notes.append(f"the {what} is stored rotated (EXIF orientation {orientation}): used upright, "
                             f"{upright.width}x{upright.height}")
            if upright.mode == "F":
                raise InputError(path, f"is a 32-bit floating-point image: this program reads 8- and 16-bit {what}s "
                                       "(save it as an 8- or 16-bit PNG or TIFF)")
            if upright.mode in ("I;16", "I;16B", "I;16L", "I"):
                notes.append(f"the {what} is 16-bit: reduced to 8 bits")
                arr = (np.asarray(upright, dtype=np.float64) / 257.0).round().clip(0, 255).astype(np.uint8)
            else:
                if upright.mode not in ("L", "RGB", "RGBA"):
                    upright = upright.convert("RGBA" if "A" in upright.getbands() else "RGB")
                if icc and colours and upright.mode in ("RGB", "RGBA"):
                    upright = to_srgb(upright, icc, path, what, notes)
                arr = np.asarray(upright, dtype=np.uint8)
    except InputError:
        raise
    except Image.DecompressionBombError:
        raise _too_many_pixels(path, what) from None
    except Exception as exc:
        if "cannot identify image file" in str(exc):  # Pillow's words name its buffer, not the file
            raise InputError(path, f"cannot read the {what}: not an image this program reads (PNG, JPEG, TIFF, WebP, BMP)") from None
        raise InputError(path, f"cannot read the {what} ({exc})") from None
    if arr.size == 0:
        raise InputError(path, f"the {what} has no pixels")
    return arr


def to_srgb(image, icc: bytes, path, what: str, notes: list):
    """``image`` (RGB or RGBA) with colours in the ICC profile ``icc`` converted to sRGB (relative
    colorimetric, LittleCMS); unchanged when the profile is sRGB's already. A profile LittleCMS
    cannot read is one line naming the file."""
    import io

    from PIL import ImageCms

    try:
        source = ImageCms.ImageCmsProfile(io.BytesIO(icc))
        name = (ImageCms.getProfileDescription(source) or "").strip()
    except (OSError, ImageCms.PyCMSError) as exc:
        raise InputError(path, f"the {what}'s embedded colour profile cannot be read ({exc})") from None
    if "srgb" in name.lower().replace(" ", ""):
        return image
    alpha = image.getchannel("A") if image.mode == "RGBA" else None
    try:
        rgb = ImageCms.profileToProfile(image.convert("RGB"), source, ImageCms.createProfile("sRGB"), outputMode="RGB",
                                        renderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC)
    except ImageCms.PyCMSError as exc:
        raise InputError(path, f"the {what}'s colours cannot be converted from its profile {name!r} to sRGB ({exc})") from None
    notes.append(f"the {what}'s colours converted from its embedded profile {name!r} to sRGB")
    if alpha is not None:
        rgb.putalpha(alpha)
    return rgb


def check_photo_file(path) -> None:
    """The photo's checks that decode no pixel, each one line: a file of another kind (a map, a light
    file) given as a photo, not a regular file, more pixels than the limit by its header. A command
    runs them before it loads the networks (torch alone takes about 2 s), so a wrong file is said at
    once; a file the header reader cannot open is left to :func:`read_photo`, which says why."""
    from PIL import Image, UnidentifiedImageError

    wrong = wrong_kind(path, "a photo")
    if wrong is not None:
        raise wrong
    path = regular_file(path, "photo")
    try:
        with open_image_header(path) as im:
            size = im.size
    except Image.DecompressionBombError:
        raise _too_many_pixels(path, "photo") from None
    except (OSError, UnidentifiedImageError, ValueError):
        return
    check_pixels(path, *size, MAX_PIXELS)


def open_image_header(source):
    """Pillow's image at ``source`` (a path or a buffer), its header read and no pixel decoded, under
    this program's pixel limit; Pillow's warning below twice the limit is silenced (``check_pixels``
    refuses such a size in one line), its error above it is :func:`_too_many_pixels`."""
    from PIL import Image

    Image.MAX_IMAGE_PIXELS = MAX_IMAGE_PIXELS  # (Pillow's limit is the process's: always the one constant)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)
        return Image.open(source)


def _too_many_pixels(path, what: str) -> InputError:
    return InputError(path, f"the {what} has more than {MAX_PIXELS // 1_000_000} megapixels")


def read_photo(path, notes: list, digests: dict | None = None, lens: dict | None = None) -> np.ndarray:
    """The photo as (H, W, 3) uint8 sRGB, upright. Grayscale becomes RGB and alpha is dropped,
    each with a note. ``digests``, ``lens``: see :func:`read_image_u8`."""
    wrong = wrong_kind(path, "a photo")
    if wrong is not None:
        raise wrong
    photo = read_image_u8(path, "photo", notes, digests, lens=lens)
    if min(photo.shape[:2]) < MIN_PERSON_PX:
        raise InputError(path, f"is {photo.shape[1]}x{photo.shape[0]} pixels: a photo of a person needs at least "
                               f"{MIN_PERSON_PX} pixels a side")
    if photo.ndim == 2:
        notes.append("the photo is grayscale: used as RGB")
        photo = np.repeat(photo[..., None], 3, axis=-1)
    elif photo.shape[-1] == 4:
        notes.append("the photo's alpha channel is ignored (the person mask says where the person is)")
        photo = photo[..., :3]
    return np.ascontiguousarray(photo)


MAX_GREY_FRACTION = 0.25  # of a mask's pixels between 10 % and 90 %


def read_mask(path, photo_shape: tuple[int, int], notes: list, digests: dict | None = None) -> np.ndarray:
    """A person mask file as a matte (H, W) float32 in [0, 1] matching the upright photo: grey
    or RGB (first channel). A mask drawn on the photo as stored (before its EXIF rotation) is
    refused with that hint."""
    img = read_image_u8(path, "mask", notes, digests, colours=False)
    if img.ndim == 3:
        img = img[..., 0]
    h, w = photo_shape
    if img.shape != (h, w):
        if img.shape == (w, h) and h != w:
            raise InputError(path, f"is {img.shape[1]}x{img.shape[0]} pixels but the upright photo is {w}x{h}: "
                                   "the mask looks drawn on the photo before its EXIF rotation; turn it upright")
        raise InputError(path, f"is {img.shape[1]}x{img.shape[0]} pixels but the photo is {w}x{h}: a mask must match its photo")
    matte = img.astype(np.float32) / 255.0
    grey = float(((matte > 0.1) & (matte < 0.9)).mean())
    if grey > MAX_GREY_FRACTION:  # hand-made masks have < 1 % (soft edges); a photo has ~95 %
        raise InputError(path, f"is not a person mask: {grey:.0%} of its pixels are neither person nor background "
                               "(a mask is black and white, soft at the edges at most; is it the photo?)")
    if not (matte > 0.5).any():
        raise InputError(path, "no person in the mask (no pixel is above 50 %)")
    return matte


def square(image: np.ndarray, top: int, left: int, side: int, mode: str) -> np.ndarray:
    """The ``side``-pixel square of ``image`` whose top-left corner is (``top``, ``left``) (either
    may be negative); outside the image: its edge repeated (``edge``) or zero (``constant``)."""
    h, w = image.shape[:2]
    pad = [(max(0, -top), max(0, top + side - h)), (max(0, -left), max(0, left + side - w))]
    pad += [(0, 0)] * (image.ndim - 2)
    padded = np.pad(image, pad, mode=mode) if any(a or b for a, b in pad[:2]) else image
    t, l = top + pad[0][0], left + pad[1][0]
    return padded[t:t + side, l:l + side]


def person_box(mask: np.ndarray) -> tuple[int, int, int, int]:
    """(top, left, height, width) of the mask's bounding box."""
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    return int(rows[0]), int(cols[0]), int(rows[-1] - rows[0] + 1), int(cols[-1] - cols[0] + 1)


def check_person(mask: np.ndarray, path) -> None:
    """Refuse an empty mask or a person too small to relight, naming ``path``."""
    if not mask.any():
        raise NoPersonError(path, "no person in the mask")
    _, _, h, w = person_box(mask)
    if max(h, w) < MIN_PERSON_PX:
        raise NoPersonError(path, f"the person is {max(h, w)} pixels tall; at least {MIN_PERSON_PX} are needed")
