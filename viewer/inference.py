"""Photo -> scene bundle: the one-time inference of the paper's Stage 1 and Stage 2 networks.

``infer(photo, mask)`` reads a photo and its person mask, frames the person the way the training
images frame them (a square around the mask, the person ``FILL`` of its height, padded by
repeating the photo's edge), runs the inverse-rendering network (normal, albedo, specular,
roughness and the photo's own area lights) on the photo with its background, and the depth network
on the person, then writes a scene bundle at ``size`` pixels: the maps, the mask, the framed photo
(also as the background), the estimated input lighting ``lights.json``, and ``inference.json``
(where everything came from, timings).

The networks run at their training resolution (``NETWORK_RES``); their maps are extended a few
pixels past the mask (so that upsampling does not mix in what the networks say about the
background) and upsampled to the bundle's size; the mask comes from the full-resolution mask.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .resources import network_dir

NETWORK_RES = 256
FILL = 0.86  # of the square the person's height spans (the middle of the dataset's range)
MIN_PERSON_PX = 32  # a person shorter than this in the photo is refused
MAX_PIXELS = 200_000_000
NETWORKS = ("inverse", "depth")


@dataclass(frozen=True)
class Framing:
    """The square of the photo the networks see: top-left corner (may be negative) and side, pixels."""

    top: int
    left: int
    side: int

    def to_json(self) -> dict:
        return {"top": self.top, "left": self.left, "side": self.side}


def read_photo(photo_path, mask_path) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(photo (H, W, 3) uint8 sRGB, mask (H, W) bool, notes). Grayscale photos become RGB, alpha is
    dropped, 16-bit images are reduced to 8 bits; a mask may be grayscale or RGB (first channel)."""
    from PIL import Image

    Image.MAX_IMAGE_PIXELS = MAX_PIXELS
    notes = []
    photo = _read_u8(photo_path, notes, "photo")
    if photo.ndim == 2:
        notes.append("the photo is grayscale: used as RGB")
        photo = np.repeat(photo[..., None], 3, axis=-1)
    elif photo.shape[-1] == 4:
        notes.append("the photo's alpha channel is ignored (the mask says where the person is)")
        photo = photo[..., :3]
    mask_img = _read_u8(mask_path, notes, "mask")
    mask = (mask_img if mask_img.ndim == 2 else mask_img[..., 0]) > 127
    if mask.shape != photo.shape[:2]:
        raise InputError(mask_path, f"is {mask.shape[1]}x{mask.shape[0]} pixels but the photo {Path(photo_path).name} is "
                                    f"{photo.shape[1]}x{photo.shape[0]}: a mask must match its photo")
    if not mask.any():
        raise InputError(mask_path, "no person in the mask (no pixel is above 50 %)")
    rows = np.flatnonzero(mask.any(axis=1))
    if rows[-1] - rows[0] + 1 < MIN_PERSON_PX:
        raise InputError(mask_path, f"the person is {rows[-1] - rows[0] + 1} pixels tall; at least {MIN_PERSON_PX} are needed")
    if mask.all():
        notes.append("the mask covers the whole photo: there is no background to read the lighting from")
    return photo, mask, notes


def _read_u8(path, notes: list, what: str) -> np.ndarray:
    from PIL import Image

    path = Path(path)
    if not path.is_file():
        raise InputError(path, f"{what} not found")
    try:
        with Image.open(path) as im:
            im.load()
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                notes.append(f"the {what} is 16-bit: reduced to 8 bits")
                arr = (np.asarray(im, dtype=np.float64) / 257.0).round().clip(0, 255).astype(np.uint8)
            else:
                if im.mode not in ("L", "RGB", "RGBA"):
                    im = im.convert("RGBA" if "A" in im.getbands() else "RGB")
                arr = np.asarray(im, dtype=np.uint8)
    except InputError:
        raise
    except Exception as exc:
        raise InputError(path, f"cannot read the {what} ({exc})") from None
    return arr


def framing(mask: np.ndarray) -> Framing:
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    height, width = rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1
    side = int(np.ceil(max(height / FILL, width / 0.95)))
    cy, cx = (rows[0] + rows[-1] + 1) / 2.0, (cols[0] + cols[-1] + 1) / 2.0
    return Framing(int(round(cy - side / 2.0)), int(round(cx - side / 2.0)), side)


def crop(image: np.ndarray, f: Framing, mode: str) -> np.ndarray:
    """The framing's square of ``image``; outside the photo: its edge repeated (``edge``) or zero."""
    h, w = image.shape[:2]
    pad = [(max(0, -f.top), max(0, f.top + f.side - h)), (max(0, -f.left), max(0, f.left + f.side - w))]
    pad += [(0, 0)] * (image.ndim - 2)
    padded = np.pad(image, pad, mode=mode) if any(a or b for a, b in pad[:2]) else image
    t, l = f.top + pad[0][0], f.left + pad[1][0]
    return padded[t:t + f.side, l:l + f.side]


def resize(image: np.ndarray, size: int) -> np.ndarray:
    """Area-filtered (down) or bicubic (up) resize of a uint8 image to size x size."""
    from PIL import Image

    return np.asarray(Image.fromarray(image).resize((size, size), Image.Resampling.BOX if image.shape[0] > size
                                                    else Image.Resampling.BICUBIC))


def extend(values, mask, steps: int = 6):
    """Fill the pixels next to the mask with the mean of their filled neighbours, ``steps`` rings."""
    import torch
    from torch.nn import functional as F

    known = mask.clone()
    v = values * known
    for _ in range(steps):
        total = F.avg_pool2d(v, 3, 1, 1, count_include_pad=False)
        weight = F.avg_pool2d(known, 3, 1, 1, count_include_pad=False)
        grow = (weight > 0) & (known < 0.5)
        v = torch.where(grow, total / weight.clamp_min(1e-6), v)
        known = torch.where(grow, torch.ones_like(known), known)
    return v


def cached_bundle(photo_path, mask_path, size: int = 512, device: str = "cpu", networks_dir=None,
                  progress=None) -> tuple[Path, bool]:
    """(bundle directory, whether it was cached): inference runs once per (photo, mask, size,
    weights); the bundle is kept beside the light cache (``bundles/``)."""
    import hashlib
    import shutil

    from .lightfit.cache import cache_dir

    h = hashlib.sha256()
    networks_dir = Path(networks_dir) if networks_dir is not None else network_dir()
    for path in (photo_path, mask_path, *(networks_dir / f"{n}.safetensors" for n in NETWORKS)):
        path = Path(path)
        if not path.is_file():
            raise InputError(path, "not found")
        h.update(path.read_bytes())
    h.update(str(size).encode())
    out = cache_dir().with_name("bundles") / f"{Path(photo_path).stem}-{h.hexdigest()[:16]}"
    if (out / "inference.json").is_file():
        return out, True
    tmp = out.with_name(out.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    infer(photo_path, mask_path, tmp, size=size, device=device, networks=load_networks(device, networks_dir),
          progress=progress)
    shutil.rmtree(out, ignore_errors=True)
    tmp.rename(out)
    return out, False


def load_networks(device="cpu", directory=None) -> dict:
    from .nets.train import load_network

    directory = Path(directory) if directory is not None else network_dir()
    return {name: load_network(directory / f"{name}.safetensors", device) for name in NETWORKS}


def infer(photo_path, mask_path, out_dir, size: int = 512, device: str = "cpu", networks: dict | None = None,
          progress=None) -> dict:
    """Write the scene bundle of ``photo_path`` into ``out_dir``; returns the record also written
    as ``inference.json``."""
    import torch

    from .camera import Camera
    from .imageio import srgb_to_linear
    from .lights import AreaLights
    from .nets import depth as depth_net
    from .nets import inverse as inverse_net
    from .scene import Scene, save_scene

    if not 64 <= size <= 4096:
        raise InputError(None, f"--size must be within [64, 4096] pixels, got {size}")
    times = {}
    t0 = time.perf_counter()

    def step(name):
        nonlocal t0
        now = time.perf_counter()
        times[name] = round(now - t0, 3)
        t0 = now
        if progress is not None:
            progress(name)

    photo, mask, notes = read_photo(photo_path, mask_path)
    f = framing(mask)
    photo_sq, mask_sq = crop(photo, f, "edge"), crop(mask.astype(np.uint8) * 255, f, "constant")
    small = srgb_to_linear(resize(photo_sq, NETWORK_RES).astype(np.float32) / 255.0)
    small_mask = resize(mask_sq, NETWORK_RES) > 127
    step("read")
    nets = networks if networks is not None else load_networks(device)
    step("load networks")
    dev = torch.device(device)
    with torch.no_grad():
        linear = torch.from_numpy(small).permute(2, 0, 1)[None].to(dev)
        m = torch.from_numpy(small_mask.astype(np.float32))[None, None].to(dev)
        maps, (direction, sigma, intensity), scale = inverse_net.predict(nets["inverse"], linear, m)
        step("inverse rendering")
        cam = Camera(size, size)
        depth = depth_net.predict(nets["depth"], linear, m, cam.distance)
        step("depth")
        stack = torch.cat([maps["albedo"], maps["specular"], maps["roughness"], maps["normal"], depth], dim=1)
        stack = extend(stack, m)
        big = torch.nn.functional.interpolate(stack, size=(size, size), mode="bilinear", align_corners=False)[0]
        big = big.permute(1, 2, 0).cpu().numpy()
    big_mask = resize(mask_sq, size) > 127
    normal = big[..., 5:8] / np.maximum(np.linalg.norm(big[..., 5:8], axis=-1, keepdims=True), 1e-6)
    keep = big_mask[..., None]
    big_photo = srgb_to_linear(resize(photo_sq, size).astype(np.float32) / 255.0).astype(np.float32)
    scene = Scene(albedo=np.where(keep, np.clip(big[..., :3], 0, 1), 0).astype(np.float32),
                  specular=np.where(big_mask, np.clip(big[..., 3], 0, 1), 0).astype(np.float32),
                  roughness=np.where(big_mask, np.clip(big[..., 4], 0, 1), 0).astype(np.float32),
                  normal=np.where(keep, normal, 0).astype(np.float32),
                  depth=np.where(big_mask, np.maximum(big[..., 8], 0.1), cam.distance).astype(np.float32),
                  mask=big_mask, camera=cam, photo=big_photo, background=big_photo)
    out_dir = Path(out_dir)
    save_scene(scene.validate(), out_dir)
    lights = AreaLights(direction[0].cpu().numpy(), sigma[0].cpu().numpy(), intensity[0].cpu().numpy())
    lights.save(out_dir / "lights.json", fit={"source": Path(photo_path).name, "method": "inverse-rendering network"})
    step("write")
    record = {"photo": str(photo_path), "mask": str(mask_path), "size": size, "network_resolution": NETWORK_RES,
              "framing": f.to_json(), "photo_size": [int(photo.shape[1]), int(photo.shape[0])], "notes": notes,
              "exposure_scale": float(scale[0, 0, 0]), "device": str(dev), "seconds": times,
              "seconds_total": round(sum(times.values()), 3)}
    (out_dir / "inference.json").write_text(json.dumps(record, indent=1) + "\n")
    return record

