"""Layers for compositors: one multi-layer EXR per frame, channels named ``layer.R/G/B`` as Nuke and
Blender read them (OpenEXR's convention; the unnamed ``R G B A`` is the beauty over its background,
the EXR a frame writes beside its PNG).

    R G B A                  the frame as composited (the background, the person over it)
    person.R/G/B/A           the relit person alone and its matte:  person = albedo x diffuse + specular
    albedo.R/G/B             the detail albedo the frame composite multiplies (the photo's, delit)
    diffuse.R/G/B            sum_l V_l I_l S_diff_l: the shadowed diffuse shading
    specular.R/G/B           sum_l V_l I_l S_spec_l, with the albedo's fine detail (as the frame composite draws it)
    unshadowed.R/G/B         the diffuse shading with every light's visibility 1
    visibility.Y             diffuse / unshadowed (luminance): 0 in full shadow, 1 lit, for regrading shadows
    normal.X/Y/Z, depth.Z    the scene's maps (camera space, metres), brought to the frame's size
    light<k>.diffuse.R/G/B   per light (``per_light``): V_k I_k S_diff_k, brought to the frame's size

All float32, linear, at the frame's size. The person's layers are those of a photo's bundle (a frame
layer); a scene without one has no detail albedo at the output size and is refused. A clip's frame
with no person in it (:func:`background_channels`) has the same channels: the background in ``R G B
A``, zero in the person's, visibility 1."""

from __future__ import annotations

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import MARK, atomic_path
from viewer.stop_signals import held

LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


def layer_channels(engine, scene, per_light: bool = False) -> dict[str, np.ndarray]:
    """The channels of the engine's current frame (after ``render``), by name."""
    if scene.frame is None:
        raise InputError(scene.source, "layers are written for a photo's bundle (relight infer): this scene has no frame layer")
    out = engine.output
    composited = out.read_output_hdr()
    person = out.read_hdr_rgba()
    diffuse, specular = out.read_frame_shading()
    frame = scene.frame
    height, width = person.shape[:2]
    albedo = frame.resized((width, height)).albedo
    shadows = engine.look.shadows
    engine.set_look(engine.looks.asked.replace(shadows="none"))  # the same lights unshadowed, then back
    engine.render(display=False)
    unshadowed = out.read_frame_shading()[0]
    engine.set_look(engine.looks.asked.replace(shadows=shadows))
    lit = np.einsum("hwc,c->hw", diffuse, LUMA)
    full = np.einsum("hwc,c->hw", unshadowed, LUMA)
    visibility = np.where(full > 1e-12, np.clip(lit / np.maximum(full, 1e-12), 0.0, 1.0), 1.0).astype(np.float32)
    channels = {**_rgb("", composited[..., :3]), "A": composited[..., 3],
                **_rgb("person.", person[..., :3]), "person.A": person[..., 3],
                **_rgb("albedo.", albedo), **_rgb("diffuse.", diffuse), **_rgb("specular.", specular),
                **_rgb("unshadowed.", unshadowed), "visibility.Y": visibility}
    normal, depth = _to_frame(scene.normal, (width, height)), _to_frame(scene.depth, (width, height))
    channels.update({f"normal.{a}": normal[..., i] for i, a in enumerate("XYZ")})
    channels["depth.Z"] = depth
    if per_light:
        for k in range(len(engine.lights)):
            planes = out.read_light(k)
            rgb = engine.lights.intensity[k][None, None, :] * (planes["visibility_soft"] * planes["diffuse"])[..., None]
            channels.update(_rgb(f"light{k}.diffuse.", _to_frame(rgb, (width, height))))
    return {name: np.ascontiguousarray(a, np.float32) for name, a in channels.items()}


def background_channels(engine, per_light: bool = False) -> dict[str, np.ndarray]:
    """The channels of :func:`layer_channels` for a picture with no person in it (a clip's frame the
    person has left): the engine's background (its current look) in ``R G B A``, nothing else."""
    background = engine.output.read_background_hdr()
    zero = np.zeros(background.shape[:2], np.float32)
    channels = {**_rgb("", background[..., :3]), "A": background[..., 3], "person.A": zero, "visibility.Y": zero + 1.0,
                "depth.Z": zero, **{f"normal.{a}": zero for a in "XYZ"}}
    for prefix in ("person.", "albedo.", "diffuse.", "specular.", "unshadowed.") + \
            tuple(f"light{k}.diffuse." for k in range(len(engine.lights) if per_light else 0)):
        channels.update({f"{prefix}{c}": zero for c in "RGB"})
    return {name: np.ascontiguousarray(a, np.float32) for name, a in channels.items()}


def _rgb(prefix: str, image: np.ndarray) -> dict[str, np.ndarray]:
    return {f"{prefix}{c}": image[..., i] for i, c in enumerate("RGB")}


def _to_frame(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A map of the scene's work resolution at the frame's ``size`` (width, height), bilinear."""
    from viewer.resize import resize

    return np.asarray(resize(np.asarray(image, np.float32), size), np.float32)


def write_layers(path, channels: dict[str, np.ndarray]):
    """One ZIP-compressed scanline EXR with every channel, written atomically."""
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, MARK[0]: MARK[1]}
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as stream, held():  # OpenEXR calls back into Python: see stop_signals.held
            OpenEXR.File(header, channels).write(stream)
    return path
