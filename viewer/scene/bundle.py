"""The scene bundle: the per-pixel maps that inference produces and the engine renders.

A scene bundle is a directory (format described in docs/scene-bundle.md):

=================  ===========================================================================
scene.json         {"format": "relight-scene", "version": 1, "width", "height", "camera": {...},
                   "depth_units": "metres", "maps": {name: file}}
albedo.exr         diffuse albedo, linear RGB in [0, 1]
specular.exr       specular reflectance in [0, 1] (Disney ``specular``; F0 = 0.08 * specular)
roughness.exr      perceptual roughness in [0, 1] (alpha = roughness^2)
normal.exr         unit normals in camera space (x right, y up, z towards the camera)
depth.exr          distance along the view axis in metres (> 0), float32
mask.png           8-bit, person where > 127
photo.png          optional: the input photo, sRGB
background.png     optional: the photo's background (person removed), sRGB
frame_photo.png    optional (version 2): the photo at output resolution, sRGB
frame_alpha.png    optional (version 2): the person's soft matte at output resolution, 16-bit
frame_albedo.exr   optional (version 2): the detail albedo at output resolution, linear RGB
frame_skin.png     optional in a frame: how much each frame pixel is skin (8-bit share), where light scatters
=================  ===========================================================================

Only pixels inside the mask carry data; loading zeroes everything outside it. The three
``frame_*`` files form the :class:`FrameLayer`: the photo's own frame (its aspect, the person where
the photo had them) at the output resolution, over the same field of view as the maps (see
:mod:`viewer.photo.frames`). A bundle made from a photo has one; a synthetic scene need not.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import linear_to_srgb, read_exr, read_json, read_png, srgb_to_linear, write_exr, write_png, write_text
from viewer.files.kinds import PHOTO_SUFFIXES, wrong_kind
from viewer.scene.camera import Camera

FORMAT = "relight-scene"
VERSION = 2  # 2: the frame layer (version 1 bundles load as before)
MAP_FILES = {
    "albedo": "albedo.exr",
    "specular": "specular.exr",
    "roughness": "roughness.exr",
    "normal": "normal.exr",
    "depth": "depth.exr",
    "mask": "mask.png",
}
OPTIONAL_FILES = {"photo": "photo.png", "background": "background.png"}
FRAME_FILES = {"photo": "frame_photo.png", "alpha": "frame_alpha.png", "albedo": "frame_albedo.exr"}
FRAME_SKIN_FILE = "frame_skin.png"  # optional in a frame (version 2 bundles before it have none)
MAX_SKIN_MM = 1e3  # millimetres a frame pixel may span (a person a few pixels tall)
ASPECT_TOLERANCE_PX = 1.5  # the frame and the maps may differ by rounding only



def bounding_box(mask: np.ndarray) -> tuple[int, int, int, int]:
    """(x, y, width, height) of the smallest box holding ``mask``'s pixels (one pixel at the corner
    when it has none)."""
    rows, cols = np.nonzero(mask)
    if not rows.size:
        return (0, 0, 1, 1)
    return (int(cols.min()), int(rows.min()), int(cols.max() - cols.min() + 1), int(rows.max() - rows.min() + 1))


@dataclass
class FrameLayer:
    """The photo's frame at output resolution (what the final composite draws): the detail
    albedo, the person's soft matte and the photo, float32, row 0 at the top. It covers the field
    of view of the scene's maps, at ``width / scene.width`` times their resolution."""

    albedo: np.ndarray  # (Hf, Wf, 3) linear, [0, 1]
    alpha: np.ndarray  # (Hf, Wf) [0, 1]
    photo: np.ndarray  # (Hf, Wf, 3) linear
    background_blur: float = 0.0  # radians: the photo's own background defocus, a Gaussian's sigma (viewer.scene.backdrop)
    skin: np.ndarray | None = None  # (Hf, Wf) [0, 1]: how much each pixel is skin (viewer.photo.gloss); None: no skin known
    skin_mm: float = 0.0  # millimetres of the person a frame pixel spans (the skin's light scatters millimetres); 0: unknown
    focal_35mm: float = 0.0  # the photo's lens, 35-mm equivalent, from its EXIF (spanning the frame's longer side); 0: unknown
    face_box: tuple | None = None  # (x, y, width, height) of the person's face, fractions of the frame; None: none found

    @property
    def height(self) -> int:
        return int(self.alpha.shape[0])

    @cached_property
    def texels(self) -> tuple[bytes, bytes]:
        """The frame's two images as the engine uploads them, packed once: the photo with alpha 1 and
        the detail albedo with the matte, RGBA float16 each. The window packs them on the thread that
        opened the scene (at 2048 pixels ~65 ms that the frame showing the person would wait)."""
        ones = np.ones(self.alpha.shape, np.float32)
        return (np.dstack([self.photo, ones]).astype(np.float16).tobytes(),
                np.dstack([self.albedo, self.alpha]).astype(np.float16).tobytes())

    @cached_property
    def box(self) -> tuple[int, int, int, int]:
        """(x, y, width, height): the smallest box holding the matte (one pixel at the corner when it is empty)."""
        return bounding_box(self.alpha > 0)

    @property
    def width(self) -> int:
        return int(self.alpha.shape[1])

    def resized(self, size: tuple[int, int]) -> FrameLayer:
        """The layer at ``size`` = (width, height) (area average down, bilinear up)."""
        from viewer.resize import resize

        if size == (self.width, self.height):
            return self
        return FrameLayer(albedo=np.clip(resize(self.albedo, size), 0, 1), alpha=np.clip(resize(self.alpha, size), 0, 1),
                          photo=np.maximum(resize(self.photo, size), 0), background_blur=self.background_blur,
                          skin=None if self.skin is None else np.clip(resize(self.skin, size), 0, 1),
                          skin_mm=self.skin_mm * self.width / size[0], focal_35mm=self.focal_35mm, face_box=self.face_box)

    def validate(self, maps_size: tuple[int, int], base: Path | None = None) -> FrameLayer:
        def file(name):
            fname = {**FRAME_FILES, "skin": FRAME_SKIN_FILE}[name]
            return base / fname if base is not None else fname

        h, w = self.alpha.shape[:2] if self.alpha.ndim >= 2 else (0, 0)
        if self.alpha.ndim != 2 or h < 1 or w < 1:
            raise InputError(file("alpha"), f"the matte must be one channel with pixels, got shape {self.alpha.shape}")
        for name, shape in (("albedo", (h, w, 3)), ("photo", (h, w, 3)), ("alpha", (h, w)), ("skin", (h, w))):
            if getattr(self, name) is None and name == "skin":
                continue
            arr = np.asarray(getattr(self, name), np.float32)
            if arr.ndim == 3 and arr.shape[-1] == 4:
                arr = arr[..., :3]
            if arr.shape != shape:
                raise InputError(file(name), f"shape {arr.shape} does not match the frame's {w}x{h}")
            if not np.isfinite(arr).all():
                raise InputError(file(name), "contains NaN or Inf")
            lo, hi = float(arr.min()), float(arr.max())
            if name != "photo" and (lo < -1e-3 or hi > 1 + 1e-3):
                raise InputError(file(name), f"values must lie in [0, 1], found [{lo:.4g}, {hi:.4g}]")
            setattr(self, name, np.ascontiguousarray(np.clip(arr, 0.0, None if name == "photo" else 1.0)))
        blur = self.background_blur
        if isinstance(blur, bool) or not isinstance(blur, (int, float)) or not 0.0 <= float(blur) <= 1.0:
            raise InputError(base / "scene.json" if base is not None else "scene.json",
                             f"frame background_blur must be an angle in [0, 1] radians, got {blur!r}")
        self.background_blur = float(blur)
        mm = self.skin_mm
        if isinstance(mm, bool) or not isinstance(mm, (int, float)) or not 0.0 <= float(mm) <= MAX_SKIN_MM:
            raise InputError(base / "scene.json" if base is not None else "scene.json",
                             f"frame skin_mm must be millimetres per pixel in [0, {MAX_SKIN_MM:g}], got {mm!r}")
        self.skin_mm = float(mm)
        focal = self.focal_35mm
        if isinstance(focal, bool) or not isinstance(focal, (int, float)) or not (focal == 0.0 or 4.0 <= float(focal) <= 2000.0):
            raise InputError(base / "scene.json" if base is not None else "scene.json",
                             f"frame focal_35mm must be a lens in [4, 2000] mm (0: unknown), got {focal!r}")
        self.focal_35mm = float(focal)
        box = self.face_box
        if box is not None:
            try:
                box = tuple(float(v) for v in box if not isinstance(v, bool))
            except (TypeError, ValueError):
                box = ()
            if len(box) != 4 or not all(np.isfinite(box)) or min(box) < 0 or box[2] <= 0 or box[3] <= 0 \
                    or box[0] + box[2] > 1 + 1e-4 or box[1] + box[3] > 1 + 1e-4:
                raise InputError(base / "scene.json" if base is not None else "scene.json",
                                 f"frame face_box must be [x, y, width, height], fractions of the frame, got {self.face_box!r}")
            self.face_box = box
        mw, mh = maps_size
        if abs(w * mh / mw - h) > ASPECT_TOLERANCE_PX * max(1.0, h / mh):
            raise InputError(file("alpha"), f"the frame {w}x{h} does not have the aspect of the maps ({mw}x{mh})")
        return self
NORMAL_TOLERANCE = 1e-2  # | |n| - 1 | allowed inside the mask before loading refuses the map
MAX_DEPTH = 1e4  # metres; a larger depth is a corrupt pixel, not a photographed person


@dataclass
class Scene:
    """Per-pixel maps of one photo. Arrays are float32, (H, W[, C]), row 0 at the top."""

    albedo: np.ndarray  # (H, W, 3) linear RGB
    specular: np.ndarray  # (H, W)
    roughness: np.ndarray  # (H, W)
    normal: np.ndarray  # (H, W, 3) camera space, unit length inside the mask
    depth: np.ndarray  # (H, W) metres, > 0 inside the mask
    mask: np.ndarray  # (H, W) bool
    camera: Camera
    photo: np.ndarray | None = None  # (H, W, 3) linear RGB
    background: np.ndarray | None = None  # (H, W, 3) linear RGB
    frame: FrameLayer | None = None  # the photo's frame at output resolution
    source: Path | None = field(default=None, compare=False)

    @property
    def height(self) -> int:
        return int(self.mask.shape[0])

    @property
    def width(self) -> int:
        return int(self.mask.shape[1])

    @property
    def output_size(self) -> tuple[int, int]:
        """(width, height) of the images rendered from this scene: the frame's, else the maps'."""
        return (self.frame.width, self.frame.height) if self.frame is not None else (self.width, self.height)

    @property
    def has_specular(self) -> bool:
        """False for a matte scene: the engine then skips all specular work."""
        return bool(np.any(self.specular[self.mask] > 0.0))

    def points(self) -> np.ndarray:
        """Camera-space positions (H, W, 3) of every pixel's depth."""
        return self.camera.unproject(self.depth)

    def validate(self, where: Path | None = None, only: frozenset[str] | None = None) -> Scene:
        """Check shapes, ranges, unit normals, finiteness and a non-empty mask.

        Raises :class:`InputError` naming the offending file. Values outside the mask are
        ignored and set to zero. ``only``: the maps checked (of albedo, specular, roughness, normal,
        depth, and "frame" for the frame layer), by a stage that replaced them in a scene validated
        whole before (a clip's frame validated its scene four times: 0.13 s of 2.1 s at 1280x720);
        None: all of them.
        """
        base = Path(where) if where is not None else None
        if only is not None and not only <= {"albedo", "specular", "roughness", "normal", "depth", "frame"}:
            raise ValueError(f"no such maps to check: {sorted(only)}")
        checked = (lambda name: True) if only is None else only.__contains__

        def file(name):
            fname = MAP_FILES.get(name) or OPTIONAL_FILES.get(name) or name
            return base / fname if base is not None else fname

        h, w = self.mask.shape if self.mask.ndim == 2 else (None, None)
        if self.mask.ndim != 2:
            raise InputError(file("mask"), f"mask must be a single-channel image, got shape {self.mask.shape}")
        if h < 1 or w < 1:
            raise InputError(file("mask"), "image has no pixels")
        m = self.mask.astype(bool)
        if not m.any():
            raise InputError(file("mask"), "mask is empty: no pixel belongs to the person")
        self.mask = m
        shapes = {"albedo": (h, w, 3), "specular": (h, w), "roughness": (h, w), "normal": (h, w, 3), "depth": (h, w)}
        for name, shape in shapes.items():
            if not checked(name):
                continue
            arr = np.asarray(getattr(self, name), dtype=np.float32)
            if arr.ndim == 3 and len(shape) == 2 and arr.shape[-1] >= 1:
                arr = arr[..., 0]  # a one-channel map saved as RGB
            if arr.shape != shape:
                raise InputError(file(name), f"shape {arr.shape} does not match the mask's {shape[:2]} (expected {shape})")
            inside = arr[m]
            bad = ~np.isfinite(inside)
            if bad.any():
                raise InputError(file(name),
                                 f"{int(bad.any(axis=-1).sum() if bad.ndim > 1 else bad.sum())} pixel(s) inside the mask are NaN or Inf")
            arr = np.where(m[..., None] if arr.ndim == 3 else m, arr, 0.0).astype(np.float32)
            setattr(self, name, np.ascontiguousarray(arr))
        for name in filter(checked, ("albedo", "specular", "roughness")):
            arr = getattr(self, name)[m]
            lo, hi = float(arr.min()), float(arr.max())
            if lo < -1e-4 or hi > 1.0 + 1e-4:
                raise InputError(file(name), f"values must lie in [0, 1], found [{lo:.4g}, {hi:.4g}]")
            setattr(self, name, np.clip(getattr(self, name), 0.0, 1.0))
        if checked("normal"):
            lengths = np.linalg.norm(self.normal[m], axis=-1)
            worst = float(np.abs(lengths - 1.0).max())
            if worst > NORMAL_TOLERANCE:
                n_bad = int((np.abs(lengths - 1.0) > NORMAL_TOLERANCE).sum())
                raise InputError(file("normal"),
                                 f"{n_bad} normal(s) inside the mask are not unit length (worst | |n|-1 | = {worst:.3g})")
            self.normal = np.where(m[..., None], self.normal / np.maximum(np.linalg.norm(self.normal, axis=-1, keepdims=True), 1e-12),
                                   0.0).astype(np.float32)
        if checked("depth"):
            dmin, dmax = float(self.depth[m].min()), float(self.depth[m].max())
            if dmin <= 0.0:
                raise InputError(file("depth"), f"depth must be > 0 inside the mask, found {dmin:.4g}")
            if dmax > MAX_DEPTH:
                raise InputError(file("depth"), f"depth {dmax:.4g} m inside the mask is implausible (> {MAX_DEPTH:g} m)")
        for name in filter(checked, ("photo", "background")):
            arr = getattr(self, name)
            if arr is None:
                continue
            arr = np.asarray(arr, dtype=np.float32)
            if arr.ndim == 3 and arr.shape[-1] == 4:
                arr = arr[..., :3]
            if arr.shape != (h, w, 3):
                raise InputError(file(name), f"shape {arr.shape} does not match the mask's {(h, w)}")
            if not np.isfinite(arr).all():
                raise InputError(file(name), "contains NaN or Inf")
            setattr(self, name, np.ascontiguousarray(arr))
        if (self.camera.width, self.camera.height) != (w, h):
            raise InputError(file("scene.json"),
                             f"camera resolution {self.camera.width}x{self.camera.height} does not match the maps' {w}x{h}")
        if self.frame is not None and checked("frame"):
            self.frame.validate((w, h), base)
            if self.photo is None:  # the maps' photo and background are the frame's, at their resolution
                from viewer.resize import resize

                self.photo = np.maximum(resize(self.frame.photo, (w, h)), 0).astype(np.float32)
            if self.background is None:
                self.background = self.photo
        return self


def load_scene(path) -> Scene:
    """Load and validate a scene bundle directory."""
    path = Path(path)
    if path.is_file() and path.suffix.lower() in PHOTO_SUFFIXES:
        raise InputError(path, "is a photo: relighting needs its scene bundle (a directory of maps); make one with "
                         f"`relight infer {path.name} --mask MASK.png -o BUNDLE`, or view it with "
                         f"`relight view {path.name} --mask MASK.png`")
    if not path.is_dir():
        wrong = wrong_kind(path, "a photo or a scene bundle")
        raise wrong if wrong is not None else InputError(path, "scene bundle directory not found")
    meta_path = bundle_file(path, "scene.json", path / "scene.json")
    if not meta_path.is_file():
        images = sum(1 for p in path.iterdir() if p.suffix.lower() in PHOTO_SUFFIXES) if not meta_path.exists() else 0
        if images > 1:  # a clip saved as frames
            raise InputError(path, f"is a folder of {images} images, not a scene bundle: image sequences are not read as "
                                   "clips; make a video of them (ffmpeg -framerate 30 -pattern_type glob -i '*.png' clip.mp4) "
                                   "or give one photo")
        raise InputError(meta_path, "missing: a scene bundle needs scene.json")
    meta = read_json(meta_path, "scene bundle description")
    if not isinstance(meta, dict):
        raise InputError(meta_path, "must hold a JSON object")
    if meta.get("format") != FORMAT:
        raise InputError(meta_path, f"not a scene bundle (format is {meta.get('format')!r}, expected {FORMAT!r})")
    version = meta.get("version", 0)
    if not isinstance(version, int):
        raise InputError(meta_path, f"version must be an integer, got {version!r}")
    if version > VERSION:
        raise InputError(meta_path, f"version {version} is newer than this program reads ({VERSION})")
    if meta.get("depth_units", "metres") != "metres":
        raise InputError(meta_path, f"depth_units must be 'metres', got {meta.get('depth_units')!r}")
    maps = meta.get("maps", {})
    if not isinstance(maps, dict) or not all(isinstance(v, str) for v in maps.values()):
        raise InputError(meta_path, "maps must be an object of map name -> file name")
    files = {**MAP_FILES, **OPTIONAL_FILES, **_plain_names(maps, meta_path)}
    try:
        cam_meta = dict(meta["camera"])
        cam_meta.setdefault("width", meta["width"])
        cam_meta.setdefault("height", meta["height"])
        camera = Camera.from_json(cam_meta)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(meta_path, f"bad camera or resolution entry ({exc})") from None

    maps = {}
    for name in MAP_FILES:
        f = bundle_file(path, files[name], meta_path)
        maps[name] = read_png(f) if f.suffix.lower() in (".png", ".jpg", ".jpeg") else read_exr(f)
    mask = maps.pop("mask")
    if mask.ndim == 3:
        mask = mask[..., 0]
    said = (meta.get("width", camera.width), meta.get("height", camera.height))  # (the camera's: Scene.validate)
    if said != (mask.shape[1], mask.shape[0]):
        raise InputError(meta_path, f"says the maps are {said[0]}x{said[1]} but {files['mask']} is {mask.shape[1]}x{mask.shape[0]}")
    extra = {}
    for name in OPTIONAL_FILES:
        f = bundle_file(path, files[name], meta_path)
        if f.is_file():
            img = read_png(f)
            if img.ndim == 2:
                img = np.repeat(img[..., None], 3, axis=-1)
            extra[name] = srgb_to_linear(img[..., :3])
    frame = _load_frame(path, meta, meta_path)
    scene = Scene(mask=mask > 0.5, camera=camera, source=path, frame=frame, **maps, **extra)
    return scene.validate(path)


def _plain_names(maps: dict, meta_path: Path) -> dict:
    """Map entries must be plain file names inside the bundle (no folders, no way out of it)."""
    for name, value in maps.items():
        if not isinstance(value, str) or not value or Path(value).name != value or value in (".", ".."):
            raise InputError(meta_path, f"map {name!r}: {value!r} is not a plain file name inside the bundle")
    return maps


def bundle_file(bundle: Path, name: str, meta_path: Path) -> Path:
    """The bundle's file ``name``, refused in one line when it is a symbolic link or is not inside the
    bundle once resolved: a bundle is a closed box, whatever names it lists or leaves to the defaults."""
    f = bundle / name
    if f.is_symlink() or (f.exists() and f.resolve().parent != bundle.resolve()):
        raise InputError(meta_path, f"{name} is a symbolic link or lies outside the bundle; bundles hold their own files")
    return f


def _load_frame(path: Path, meta: dict, meta_path: Path) -> FrameLayer | None:
    entry = meta.get("frame")
    if entry is None:
        return None
    if not isinstance(entry, dict) or not isinstance(entry.get("maps", {}), dict):
        raise InputError(meta_path, "frame must be an object with width, height and maps")
    files = {**FRAME_FILES, **_plain_names(entry.get("maps", {}), meta_path)}
    photo = read_png(bundle_file(path, files["photo"], meta_path))
    if photo.ndim == 2:
        photo = np.repeat(photo[..., None], 3, axis=-1)
    alpha = read_png(bundle_file(path, files["alpha"], meta_path))
    albedo = read_exr(bundle_file(path, files["albedo"], meta_path))
    skin = None
    if "skin" in files:  # listed by the bundles that have one
        skin = read_png(bundle_file(path, files["skin"], meta_path))
        skin = skin if skin.ndim == 2 else skin[..., 0]
    frame = FrameLayer(albedo=albedo[..., :3] if albedo.ndim == 3 else albedo, alpha=alpha if alpha.ndim == 2 else alpha[..., 0],
                       photo=srgb_to_linear(photo[..., :3]), background_blur=entry.get("background_blur", 0.0),
                       skin=skin, skin_mm=entry.get("skin_mm", 0.0), focal_35mm=entry.get("focal_35mm", 0.0),
                       face_box=entry.get("face_box"))
    size = (entry.get("width"), entry.get("height"))
    if size != (frame.width, frame.height):
        raise InputError(meta_path, f"frame is {size[0]}x{size[1]} but {files['alpha']} is {frame.width}x{frame.height}")
    return frame


def save_scene(scene: Scene, path) -> Path:
    """Write a scene bundle directory (EXR for float maps, PNG for mask and photos)."""
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    write_exr(path / MAP_FILES["albedo"], scene.albedo, half=True)
    write_exr(path / MAP_FILES["specular"], scene.specular, half=True)
    write_exr(path / MAP_FILES["roughness"], scene.roughness, half=True)
    write_exr(path / MAP_FILES["normal"], scene.normal)
    write_exr(path / MAP_FILES["depth"], scene.depth)
    write_png(path / MAP_FILES["mask"], scene.mask.astype(np.float32))
    maps = dict(MAP_FILES)
    frame = scene.frame
    if frame is not None:
        write_png(path / FRAME_FILES["photo"], linear_to_srgb(frame.photo), compress_level=1)
        write_png(path / FRAME_FILES["alpha"], frame.alpha, bits=16, compress_level=1)
        write_exr(path / FRAME_FILES["albedo"], frame.albedo, half=True)
        if frame.skin is not None:
            write_png(path / FRAME_SKIN_FILE, frame.skin, compress_level=1)
    for name in OPTIONAL_FILES:
        img = getattr(scene, name)
        if img is not None and frame is None:  # with a frame, they are the frame photo's
            write_png(path / OPTIONAL_FILES[name], linear_to_srgb(img))
            maps[name] = OPTIONAL_FILES[name]
    meta = {
        "format": FORMAT,
        "version": VERSION,
        "width": scene.width,
        "height": scene.height,
        "camera": scene.camera.to_json(),
        "depth_units": "metres",
        "color_space": {"albedo": "linear", "photo": "sRGB", "background": "sRGB"},
        "normal_space": "camera (x right, y up, z towards the camera)",
        "maps": maps,
    }
    if frame is not None:
        frame_maps = dict(FRAME_FILES) | ({"skin": FRAME_SKIN_FILE} if frame.skin is not None else {})
        meta["frame"] = {"width": frame.width, "height": frame.height, "maps": frame_maps,
                         "color_space": {"photo": "sRGB", "albedo": "linear", "alpha": "linear coverage", "skin": "share"},
                         "background_blur": frame.background_blur, "skin_mm": frame.skin_mm,
                         **({"focal_35mm": frame.focal_35mm} if frame.focal_35mm else {}),
                         **({"face_box": [round(v, 5) for v in frame.face_box]} if frame.face_box is not None else {})}
    write_text(path / "scene.json", json.dumps(meta, indent=2) + "\n")
    return path
