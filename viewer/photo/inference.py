"""Photo -> scene bundle: the one-time inference (the paper's Stage 1 and Stage 2 networks), the
photo's own lighting and the detail layer.

``infer(photo, mask=None)``:

1. reads the photo upright (EXIF orientation applied) and caps it to the output frame
   (``max_size`` on the longer side, :mod:`viewer.photo.frames`); the person's matte and
   foreground colours come from the mask file, or from the automatic person segmentation
   (:mod:`viewer.photo.segmentation`), matted from the photo (:mod:`viewer.photo.matting`);
2. frames the person the way the training images frame them (a square around the matte, the
   person ``FILL`` of its height, padded by repeating the photo's edge: internal to the networks,
   never shown) and runs the inverse-rendering network (normal, albedo, specular, roughness, the
   photo's lights as the network guesses them) and the depth network at ``NETWORK_RES``;
3. brings their maps to the work frame (the photo's field of view, the person about ``size``
   pixels: the resolution of the shadow work), extended a few pixels past the mask first, so that
   resampling never mixes in what the networks say about the background; the face, fitted at its
   own resolution (:mod:`viewer.photo.face`), replaces their normals and depth where it is;
4. fits the photo's own lights to the photo (:mod:`viewer.photo.own_lighting`) with the GL engine;
5. makes the detail albedo at the frame's resolution (:mod:`viewer.photo.detail`) from the photo and its
   shading under those lights, upsampled by the same frame composite that draws every relit frame;
6. writes the scene bundle (the maps at the work frame, the frame layer, the photo's lights
   ``lights.json``, the network's guess ``lights_network.json``, ``inference.json``) into a new
   folder that replaces ``out_dir`` only when complete.
"""

from __future__ import annotations

import json
import shutil
import time
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from viewer.errors import InputError, NoPersonError
from viewer.files.imageio import read_json
from viewer.files.kinds import regular_file
from viewer.files.ownership import discard_entry, folder_lock, fresh_sibling, mark_written, names_ours, written_here
from viewer.nets.device import DEFAULT_DEVICE, compute_device
from viewer.photo import detail as detail_mod, gloss
from viewer.photo.bundle_version import NETWORKS, PIPELINE, bundle_key
from viewer.photo.frames import (
    MAX_SIZE,
    WORK_PERSON,
    check_person,
    frame_sizes,
    open_image_header,
    output_frame,
    person_box,
    read_mask,
    read_photo,
)
from viewer.photo.matting import automatic_matte, mask_matte
from viewer.photo.network_frame import NETWORK_RES, crop, extend, framing, map_stack, scene_maps, to_work_frame
from viewer.photo.person_checks import check_not_inverted, orientation_note
from viewer.photo.shading_stages import detail_stage, face_stage, fit_lights_stage, shading_stage, sheen_stage, steady_stage
from viewer.resize import mask_normalized_resize, resize
from viewer.resources import network_dir
from viewer.scene.backdrop import photo_blur

# each stage's share of the time, for the time-left estimate (viewer.progress.TimeLeft): seconds measured
# for assets/photos/underpass.jpg (681x1024) on the 2-core CPU machine, 2026-11-25
STAGE_SHARES = {"read": 0.09, "mask": 2.66, "load networks": 0.01, "inverse rendering": 0.21, "depth": 0.07,
                "maps to the work frame": 0.24, "face": 0.10, "steady along the clip": 0.05, "fit the photo's lights": 1.65,
                "render the photo's shading": 0.45, "the photo's sheen": 0.05, "detail": 0.17, "write": 0.3}


def load_networks(device=DEFAULT_DEVICE, directory=None) -> dict:
    """The networks' weights on ``device`` (:func:`viewer.nets.device.compute_device`: ``auto`` is
    CUDA where there is one)."""
    from viewer.nets.weights import load_network

    device = compute_device(device)
    directory = Path(directory) if directory is not None else network_dir()
    return {name: load_network(directory / f"{name}.safetensors", device) for name in NETWORKS}


def cached_bundle(photo_path, mask_path=None, size: int = WORK_PERSON, max_size: int = MAX_SIZE, device: str = DEFAULT_DEVICE,
                  networks_dir=None, progress=None, ctx=None, bundles=None) -> tuple[Path, bool]:
    """(bundle directory, whether it was cached): inference runs once per :func:`bundle_key`; the
    bundle is kept in ``bundles``, by default beside the light cache (``bundles/``; a batch on a
    cluster names its shared folder). A cached bundle is used only when it is whole (every file as
    this program wrote it, :func:`viewer.files.ownership.written_here`) and was made from the very bytes
    the key was (its record's ``inputs_sha256``); a damaged one is inferred again. A photo or mask
    that changes while it is inferred is one line (run again), and its bundle is not kept."""
    from viewer.lighting.lightfit.cache import bundles_dir

    expected: dict[str, str] = {}  # the SHA-256 of the photo's and mask's bytes, as the key read them
    key = bundle_key(photo_path, mask_path, size, max_size, networks_dir, digests=expected)
    out = Path(bundles or bundles_dir()) / f"{Path(photo_path).stem}-{key[:16]}"
    if out.exists() or out.is_symlink():
        if _made_from(out, expected):
            return out, True
        import warnings

        aside = discard_entry(out, names_ours(out))  # the cache's own entry, damaged or of other bytes
        warnings.warn(f"{out}: the cached bundle did not check out (a file changed, missing or added, or made from other "
                      f"bytes): {'moved aside to ' + aside.name if aside else 'removed'}, the photo is inferred again",
                      stacklevel=2)
    networks_dir = Path(networks_dir) if networks_dir is not None else network_dir()
    infer(photo_path, mask_path, out, size=size, max_size=max_size, device=device,
          networks=load_networks(device, networks_dir), progress=progress, ctx=ctx)
    if not _made_from(out, expected):
        shutil.rmtree(out, ignore_errors=True)
        raise InputError(photo_path, "changed while it was being inferred: run again once it is in place")
    return out, False


def _made_from(bundle: Path, inputs: dict) -> bool:
    """Whether ``bundle`` is whole, as this program wrote it, and made from ``inputs`` (SHA-256 of
    the photo's and the mask's bytes)."""
    if not written_here(bundle):
        return False
    try:
        return read_json(bundle / "inference.json", "inference record").get("inputs_sha256") == inputs
    except (InputError, AttributeError):
        return False


class _Stages:
    """Seconds per stage, reported to ``progress(stage)`` as each one ends."""

    def __init__(self, progress):
        self.times: dict[str, float] = {}
        self.progress = progress
        self._t = time.perf_counter()

    def __call__(self, name: str):
        now = time.perf_counter()
        self.times[name] = round(now - self._t, 3)
        self._t = now
        if self.progress is not None:
            self.progress(name)


def infer(photo_path, mask_path, out_dir, size: int = WORK_PERSON, max_size: int = MAX_SIZE, device: str = DEFAULT_DEVICE,
          networks: dict | None = None, progress=None, ctx=None, detail: str = detail_mod.DEFAULT) -> dict:
    """Write the scene bundle of ``photo_path`` into ``out_dir``; returns the record also written
    as ``inference.json``. ``mask_path`` None: the automatic person mask. ``size``: pixels of the
    person's longer side in the maps; ``max_size``: the frame's longer side."""
    bundle_target(out_dir)  # refused before the work, not after it
    result = infer_scene(photo_path, mask_path, size=size, max_size=max_size, device=device, networks=networks,
                         progress=progress, ctx=ctx, detail=detail)
    write_bundle(result, out_dir)
    if progress is not None:
        progress("write")
    return result["record"]


def _check_memory(photo_path, max_size: int) -> None:
    """Refuse, from the photo's header, a frame whose inference would not fit this machine's memory
    (a 12000x8011 photo at --max-size 12000 was killed by the kernel at 24.4 GB): viewer.memory_needs."""
    from PIL import Image, UnidentifiedImageError

    from viewer import memory_needs

    if Path(photo_path).exists() and not Path(photo_path).is_dir():  # (a folder or none: read_photo's one line)
        regular_file(photo_path, "photo")  # before it is opened: a pipe would block
    try:
        with open_image_header(photo_path) as im:  # the size is all that is read here; read_photo checks the rest
            w, h = im.size
    except (OSError, UnidentifiedImageError, ValueError, Image.DecompressionBombError):
        return  # not an image this program reads: read_photo says so in its one line
    fw, fh = output_frame((w, h), max_size)
    memory_needs.require(memory_needs.infer_bytes(w * h, fw * fh), f"a {fw}x{fh} frame from this photo",
                   f"--max-size {memory_needs.largest_frame_side(w * h, min(fw, fh) / max(fw, fh))} or less fits",
                   photo_path)


@dataclass(frozen=True)
class Stage:
    """One step of :func:`infer_scene`: ``run(**inputs)`` returns a dict of exactly its ``outputs``
    (names of the values the stages share; an output may replace a value, as each stage that
    touches the scene returns it anew). ``name`` is what the progress callback is told when it
    ends (``STAGE_SHARES`` holds its share of the time)."""

    name: str
    run: object
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]


def _read(photo_path, max_size, clip):
    notes: list[str] = []
    inputs: dict[str, str] = {}  # SHA-256 of the bytes decoded: what this bundle was made from
    lens: dict = {}  # the photo's EXIF focal length (a plate compares its perspective: viewer.plate.placement)
    if clip is None:
        _check_memory(photo_path, max_size)
        photo = read_photo(photo_path, notes, inputs, lens)
    else:  # a clip's frame, decoded and upright (viewer.photo.clip_inference): the clip's bytes are its input
        photo = clip.picture
    h, w = photo.shape[:2]
    frame = output_frame((w, h), max_size)
    return {"photo": photo, "frame": frame, "frame_photo": resize(photo, frame), "notes": notes, "inputs": inputs,
            "focal_35mm": lens.get("focal_35mm")}


def _mask(photo_path, mask_path, photo, frame, frame_photo, notes, inputs, size, max_size, clip):
    from viewer.photo.segmentation import find_person

    steady, follow, everyone_too = (clip.steady, clip.follow, clip.everyone_too) if clip is not None else (None, None, False)

    h, w = photo.shape[:2]
    if mask_path is not None:
        given = np.clip(resize(read_mask(mask_path, (h, w), notes, inputs), frame), 0.0, 1.0)
        try:  # the pose's landmarks still tell the face's skin (viewer.photo.gloss); a mask needs no person found
            landmarks = find_person(frame_photo, photo_path).landmarks
        except InputError:
            landmarks = {}
        check_not_inverted(given, landmarks, mask_path)
        matte = mask_matte(frame_photo, given)
        mask_source = str(mask_path)
    else:
        # a clip's frame: the person followed among others, and the frame before's person, carried along
        # the flow, steadies where the outline is decided
        found = find_person(frame_photo, photo_path, notes, follow, everyone_too)
        carried = steady[0].carried_matte(frame_photo, steady[1]) if steady is not None else None
        matte = automatic_matte(frame_photo, found, carried)
        if steady is not None:  # the objects found held, confirmed by the next frame's
            steady[0].found_objects(matte.objects)
        landmarks = found.landmarks
        mask_source = "automatic (MediaPipe pose segmentation, matted: viewer.photo.matting)"
    alpha = matte.alpha
    person = alpha > 0.5
    check_person(person, mask_path if mask_path is not None else photo_path)
    turned = orientation_note(landmarks)  # said now (a warning line); kept in the record's "orientation"
    if turned:
        warnings.warn(f"{photo_path}: {turned}", stacklevel=2)
    if person.all():
        notes.append("the mask covers the whole photo: there is no background to see the new lighting against")
    body = matte.body if matte.body.any() else person  # what it holds frames nothing (Matte.body)
    _, _, ph, pw = person_box(body)
    sizes = frame_sizes((w, h), (pw * w / frame[0], ph * h / frame[1]), max_size, size)
    return {"matte": matte, "landmarks": landmarks, "mask_source": mask_source, "alpha": alpha, "person": person,
            "body": body, "turned": turned, "sizes": sizes}


def _load_networks(photo_path, mask_path, frame_photo, alpha, body, networks, device):
    from viewer.files.imageio import srgb_to_linear

    f = framing(body)
    square_photo = crop(frame_photo, f, "edge")
    small = srgb_to_linear(resize(square_photo, (NETWORK_RES, NETWORK_RES)).astype(np.float32) / 255.0)
    small_mask = resize(crop(alpha, f, "constant"), (NETWORK_RES, NETWORK_RES)) > 0.5
    if not small_mask.any():
        raise NoPersonError(mask_path or photo_path, "the person is too thin to be seen at the networks' resolution")
    return {"framing": f, "small": small, "small_mask": small_mask,
            "nets": networks if networks is not None else load_networks(device)}


def _inverse_rendering(photo_path, mask_path, alpha, sizes, framing, small, small_mask, nets, device):
    import torch

    from viewer.nets import inverse as inverse_net
    from viewer.scene.camera import FULL_FRAME_MM, Camera

    work_mask = resize(alpha, sizes.work) > 0.5
    if not work_mask.any():
        raise NoPersonError(mask_path or photo_path, "the person vanishes at the work resolution; give a larger --size")
    side_work = framing.side * sizes.work_scale
    # the framing's square sees what the training camera sees: 50 mm on 36 mm across the square
    camera = Camera(sizes.work[0], sizes.work[1], sensor_mm=FULL_FRAME_MM * max(sizes.work) / side_work)
    dev = torch.device(device)
    linear = torch.from_numpy(small).permute(2, 0, 1)[None].to(dev)
    m = torch.from_numpy(small_mask.astype(np.float32))[None, None].to(dev)
    maps, network_lights, scale = inverse_net.predict(nets["inverse"], linear, m)
    return {"work_mask": work_mask, "side_work": side_work, "camera": camera, "linear": linear, "m": m, "maps": maps,
            "network_lights": network_lights, "exposure_scale": scale}


def _depth(nets, linear, m, camera):
    from viewer.nets import depth as depth_net

    return {"depth": depth_net.predict(nets["depth"], linear, m, camera.distance)}


def _maps_to_work_frame(frame_photo, matte, landmarks, sizes, framing, maps, depth, m, camera, work_mask):
    from viewer.files.imageio import srgb_to_linear
    from viewer.scene.bundle import FrameLayer, Scene

    alpha, s = matte.alpha, sizes.work_scale
    person = alpha > 0.5
    work = to_work_frame(extend(map_stack(maps, depth), m).cpu().double(), framing, sizes.work, s).astype(np.float32)
    frame_linear = srgb_to_linear(frame_photo.astype(np.float32) / 255.0)
    # upsampled from the maps extended past the mask, not from the zeroed ones: zeros mixed in at
    # the outline would darken the matte's edge (frame pixels whose work pixel is outside the mask)
    frame_network_albedo = np.where(alpha[..., None] > 0, np.clip(resize(np.clip(work[..., :3], 0, 1), sizes.frame), 0, 1),
                                    0).astype(np.float32)
    blur_px = photo_blur(frame_photo, alpha)  # the photo's own background defocus: the backdrop's "auto" blur
    scene = Scene(**scene_maps(work, work_mask, camera.distance), mask=work_mask, camera=camera,
                  frame=FrameLayer(albedo=frame_network_albedo, alpha=alpha.astype(np.float32), photo=frame_linear,
                                   background_blur=blur_px * s / camera.focal_px))
    skin = gloss.skin(matte.foreground, alpha, landmarks)  # skin keeps the network's sheen, the rest is matte
    if skin is not None:
        scene = replace(scene, roughness=np.where(work_mask, gloss.matte_roughness(
            scene.roughness, mask_normalized_resize(skin[..., None], alpha, sizes.work)[..., 0]), 0).astype(np.float32))
    gloss_record = {"skin_share": float((skin[person] > 0.5).mean()) if skin is not None else None,
                    "matte_roughness": gloss.MATTE_ROUGHNESS if skin is not None else None}
    return {"scene": scene.validate(), "frame_linear": frame_linear, "frame_network_albedo": frame_network_albedo,
            "blur_px": blur_px, "skin": skin, "gloss_record": gloss_record}


# infer_scene's stages, in order: each declares the values it reads and makes (the engine's passes
# do the same); ``engine`` is the GL engine over the scene the face stage left, made for the two
# stages that read it. A new stage: its work in a module of viewer/photo/ (as face.py, detail.py),
# and one line here.
STAGE_LIST = (
    Stage("read", _read, ("photo_path", "max_size", "clip"), ("photo", "frame", "frame_photo", "notes", "inputs", "focal_35mm")),
    Stage("mask", _mask, ("photo_path", "mask_path", "photo", "frame", "frame_photo", "notes", "inputs", "size", "max_size",
                          "clip"),
          ("matte", "landmarks", "mask_source", "alpha", "person", "body", "turned", "sizes")),
    Stage("load networks", _load_networks, ("photo_path", "mask_path", "frame_photo", "alpha", "body", "networks", "device"),
          ("framing", "small", "small_mask", "nets")),
    Stage("inverse rendering", _inverse_rendering,
          ("photo_path", "mask_path", "alpha", "sizes", "framing", "small", "small_mask", "nets", "device"),
          ("work_mask", "side_work", "camera", "linear", "m", "maps", "network_lights", "exposure_scale")),
    Stage("depth", _depth, ("nets", "linear", "m", "camera"), ("depth",)),
    Stage("maps to the work frame", _maps_to_work_frame,
          ("frame_photo", "matte", "landmarks", "sizes", "framing", "maps", "depth", "m", "camera", "work_mask"),
          ("scene", "frame_linear", "frame_network_albedo", "blur_px", "skin", "gloss_record")),
    Stage("face", face_stage, ("scene", "frame_photo", "alpha", "sizes", "skin", "body", "gloss_record", "steady"),
          ("scene", "face_record", "face_surface", "gloss_record")),
    Stage("steady along the clip", steady_stage, ("scene", "frame_photo", "steady"), ("scene", "steady_share")),
    Stage("fit the photo's lights", fit_lights_stage, ("engine", "scene", "frame_linear", "sizes", "work_mask", "side_work",
                                                        "face_surface", "given_lights"), ("lights", "fit", "target", "valid")),
    Stage("render the photo's shading", shading_stage, ("engine", "lights", "fit", "target", "valid"),
          ("explained", "shading", "fit")),
    Stage("the photo's sheen", sheen_stage, ("scene", "shading", "framing", "matte", "gloss_record"),
          ("scene", "shading", "gloss_record")),
    Stage("detail", detail_stage, ("scene", "frame_network_albedo", "shading", "framing", "matte", "detail"), ("scene", "detail_stats")),
)
ENGINE_STAGES = ("fit the photo's lights", "render the photo's shading")  # the stages that read ``engine``
STAGES = tuple(st.name for st in STAGE_LIST) + ("write",)  # what infer() reports to its progress callback, in order


def run_stages(values: dict, stage, ctx=None) -> dict:
    """Run :data:`STAGE_LIST` over ``values`` (the given ones: photo_path, mask_path, size,
    max_size, device, networks, detail, picture, given_lights, steady, follow, everyone_too), reporting
    each to ``stage``; returns every value. Under ``torch.no_grad`` (nothing here learns); the engine
    the two engine stages share is made over the scene before them and released after them,
    whatever happens."""
    import torch

    from viewer.gl import Engine, EngineOptions, create_headless_context

    own_ctx, engine = ctx is None, None
    try:
        with torch.no_grad():
            for st in STAGE_LIST:
                if st.name in ENGINE_STAGES and engine is None:
                    ctx = create_headless_context() if ctx is None else ctx
                    engine = values["engine"] = Engine(ctx, values["scene"], EngineOptions())
                out = st.run(**{k: values[k] for k in st.inputs})
                if set(out) != set(st.outputs):
                    raise RuntimeError(f"stage {st.name!r} made {sorted(out)}, declared {sorted(st.outputs)}")
                values.update(out)
                if st.name == ENGINE_STAGES[-1]:
                    engine.release()
                    engine = values["engine"] = None
                stage(st.name)
    finally:
        if engine is not None:
            engine.release()
        if own_ctx and ctx is not None:
            ctx.release()
    return values


@dataclass(frozen=True)
class ClipFrame:
    """What a clip gives one frame's inference beside its pixels' name: ``picture`` the frame decoded
    (H, W, 3) uint8 sRGB upright; ``lights`` the photo's own lights already known (the shot's, fitted on
    its first frame; None: fitted here); ``steady`` (the clip's :class:`viewer.photo.steady.SteadyMaps`,
    the frame's shot): its maps made steady; ``follow`` the clip's
    :class:`viewer.photo.person_track.PersonTrack`, the person it relights; ``everyone_too``: everyone
    found is relit (:func:`viewer.photo.segmentation.find_person`)."""

    picture: np.ndarray
    lights: object = None
    steady: tuple | None = None
    follow: object = None
    everyone_too: bool = False


def infer_scene(photo_path, mask_path=None, size: int = WORK_PERSON, max_size: int = MAX_SIZE, device: str = DEFAULT_DEVICE,
                networks: dict | None = None, progress=None, ctx=None, detail: str = detail_mod.DEFAULT,
                clip: ClipFrame | None = None) -> dict:
    """Everything :func:`infer` writes, in memory: ``scene`` (with its frame layer), ``lights``
    (the photo's, fitted), ``network_lights``, ``record``; for a photo also the network's maps and the
    photo's shading at the frame (``network_albedo_frame``, ``shading``, ``target``, ``valid``,
    ``explained``, ``foreground``: for the benchmarks; a clip's frames leave them out, their memory is the
    clip's). The work is :data:`STAGE_LIST`, run by :func:`run_stages`. ``clip``: a clip's frame
    (:class:`ClipFrame`: its pixels, ``photo_path`` then only names it in messages)."""
    import torch

    from viewer.scene.area_lights import AreaLights

    # the networks' own device when they are given (loaded for many photos), else "auto" resolved here
    device = str(next(networks["inverse"].parameters()).device) if networks is not None else compute_device(device)
    stage = _Stages(progress)
    v = run_stages({"photo_path": photo_path, "mask_path": mask_path, "size": size, "max_size": max_size,
                    "device": device,
                    "networks": networks, "detail": detail, "clip": clip, "given_lights": clip and clip.lights,
                    "steady": clip and clip.steady}, stage, ctx)
    scene, sizes, f = v["scene"], v["sizes"], v["framing"]
    if v["focal_35mm"]:  # the photo's lens, kept with its frame
        scene = replace(scene, frame=replace(scene.frame, focal_35mm=float(v["focal_35mm"])))
    direction, sigma, intensity = v["network_lights"]
    network_lights = AreaLights(direction[0].cpu().numpy(), sigma[0].cpu().numpy(), intensity[0].cpu().numpy())
    record = {"photo": str(photo_path), "mask": v["mask_source"], "inputs_sha256": v["inputs"], "orientation": v["turned"],
              "sizes": sizes.to_json(), "photo_size": list(sizes.photo), "network_resolution": NETWORK_RES,
              "framing": f.to_json(), "notes": v["notes"], "exposure_scale": float(v["exposure_scale"][0, 0, 0]),
              "device": str(torch.device(device)), "matte": v["matte"].record, "gloss": v["gloss_record"],
              "face": v["face_record"], "background_blur": {"pixels": round(v["blur_px"], 3),
                                                            "degrees": round(float(np.degrees(scene.frame.background_blur)), 4)},
              "photo_lighting": v["fit"], "detail": v["detail_stats"], "pipeline": PIPELINE,
              **({"steady_share": v["steady_share"]} if v["steady_share"] is not None else {})}
    result = {"scene": scene, "lights": v["lights"], "network_lights": network_lights, "record": record, "stages": stage}
    if clip is None:
        result.update(network_albedo_frame=v["frame_network_albedo"], shading=v["shading"], target=v["target"],
                      valid=v["valid"], explained=v["explained"], foreground=v["matte"].foreground)
    return result


def bundle_target(out_dir) -> Path:
    """``out_dir`` as a place for a scene bundle: new, empty, or a bundle this program wrote there and
    nothing else (:mod:`viewer.files.ownership`), which is replaced. Anything else is refused in one line:
    replacing it would delete or change the user's files."""
    out_dir = Path(out_dir).resolve()
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(out_dir, "exists and is not a folder: give a folder for the scene bundle")
    if out_dir.is_dir() and any(out_dir.iterdir()) and not written_here(out_dir):
        what = ("a scene bundle with files relight did not write there, or changed since" if (out_dir / "scene.json").exists()
                else "a folder with other files and no scene bundle in it")
        raise InputError(out_dir, f"is {what}: give a new or empty folder for the bundle (nothing was written)")
    return out_dir


def write_bundle(result: dict, out_dir) -> Path:
    """Write :func:`infer_scene`'s result as a scene bundle; a previous bundle in ``out_dir`` (one
    this program wrote, :func:`bundle_target`) is replaced only once the new one is complete. The
    new bundle is written into a folder of its own (a name no one else has) and swapped into place
    under a lock on the parent folder, so two writers to one output take turns."""
    from viewer.files.imageio import write_text
    from viewer.scene.bundle import save_scene

    out_dir = bundle_target(out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = fresh_sibling(out_dir, "partial")
    old = None
    try:
        save_scene(result["scene"], tmp)
        result["lights"].save(tmp / "lights.json", fit={"source": Path(result["record"]["photo"]).name,
                                                          "method": "fitted to the photo (viewer.photo.own_lighting)"})
        result["network_lights"].save(tmp / "lights_network.json",
                                      fit={"source": Path(result["record"]["photo"]).name, "method": "inverse-rendering network"})
        record = result["record"]
        record["seconds"] = dict(result["stages"].times)
        record["seconds_total"] = round(sum(record["seconds"].values()), 3)
        write_text(tmp / "inference.json", json.dumps(record, indent=1) + "\n")
        mark_written(tmp)
        with folder_lock(out_dir.parent):
            bundle_target(out_dir)  # again: another writer may have put something there meanwhile
            if out_dir.exists():
                old = fresh_sibling(out_dir, "old")
                out_dir.replace(old / "bundle")
            tmp.rename(out_dir)
    except BaseException as exc:  # a full disk, or Ctrl-C / SIGTERM: no partial folder stays behind
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None and (old / "bundle").is_dir() and not out_dir.exists():
            (old / "bundle").rename(out_dir)  # the earlier bundle back in its place
        if old is not None and not any(old.iterdir()):
            old.rmdir()
        if isinstance(exc, OSError):
            raise InputError(out_dir, f"cannot write the scene bundle ({exc})") from None
        raise
    if old is not None:  # the folder made above, holding the bundle this program wrote; a stop during the
        # removal would leave half of it behind (the campaign's SIGINT at 98 % of an infer did): it comes after
        from viewer.stop_signals import held

        with held():
            shutil.rmtree(old, ignore_errors=True)
    return out_dir
