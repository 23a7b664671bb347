"""A person rendered onto a plate and written: the engine's person and shadow, composited into the
plate where the placement says, matched to the plate's defocus and grain, written as a PNG and its
EXR (and the layers' EXR) together. ``relight render --plate`` and a batch's plate looks share it."""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from viewer.output.plate_composite import composite_on_plate
from viewer.plate.loader import Plate
from viewer.plate.match import feet_blur, grain_levels, with_grain
from viewer.plate.people import in_front
from viewer.plate.placement import Placement, PlateSpot, enlarged, landing_box, plate_transform
from viewer.scene.look import Look


def plate_look(look: Look, auto: float = 0.0) -> Look:
    """``look`` as a plate needs it: no background (the plate is), the ground's shadow unless turned off,
    and the exposure: the stops given, else ``auto``: 0 (the plate's units) lit by the plate's own
    light, the matched exposure lit by the user's (:func:`viewer.plate.exposure.matched_exposure`)."""
    from viewer.scene.look import AUTO

    exposure = float(auto) if look.exposure == AUTO else look.exposure
    return replace(look, background="transparent", ground=look.ground is not False, exposure=exposure)


def read_person(engine) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, float]:
    """The engine's last frame as a plate takes it: (the person premultiplied by their matte and
    exposed by the look, (H, W, 4); the ground's shadow share, or None without the ground; the matte
    that places them: the frame's, else the coverage; the share of the ground's light a contact
    shadow hides, :func:`viewer.plate.contact.sky_share` of the engine's lights, 0 without the ground)."""
    from viewer.plate.contact import sky_share

    person = engine.output.read_hdr_rgba()  # its colour as lit, and its coverage
    person[..., :3] *= person[..., 3:4] * 2.0 ** float(engine.look.exposure)  # premultiplied, exposed
    shadow = engine.output.read_ground_shadow() if engine.look.ground else None
    alpha = person[..., 3] if engine.scene.frame is None else engine.scene.frame.alpha
    return person, shadow, alpha, sky_share(engine.lights) if engine.look.ground else 0.0


def render_on_plate(engine, scene, lights, look: Look, spot: PlateSpot, png, exr, layers=None, layers_in_exr: bool = False,
                    fixed=None) -> dict:
    """Render ``scene`` (the engine's) under ``lights`` (and ``fixed``, a rig) and ``look`` (as
    :func:`plate_look` made it), composite it into the plate at its spot (:class:`PlateSpot`) and write
    the files (:func:`write_on_plate`). Returns what was matched: the defocus and the grain."""
    from viewer.output.render import resolve_exposure

    engine.set_lights(lights, fixed)
    engine.set_look(resolve_exposure(engine, scene, look))
    engine.render()
    return write_on_plate(read_person(engine), spot, png, exr, layers, layers_in_exr)


def composite_frame(frame: tuple, plate: Plate, place: Placement, blur: float, horizon: float | None, anchor: np.ndarray | None = None,
                    source=None, cut_allowed: bool = False, mattes: dict | None = None, focal_px: float | None = None):
    """The person of ``frame`` (:func:`read_person`'s) composited into ``plate`` at ``place`` as every plate
    output does (a still, a window's copy, a clip's frame): placed by their frame's matte, or by ``anchor``
    (a clip's first person's: every frame carried into the plate alike); a contact shadow only where the
    placing matte's soles reach the ground; the plate's people nearer than the feet hiding them (the
    place's feet, a clip's where this frame's land; their mattes kept in ``mattes`` when given). ``blur``
    the plate's defocus there (plate pixels), ``focal_px`` the plate's (its own unless given). (the
    composite, the transform, the person's box in the plate's pixels); one line when they cannot stand there."""
    person, shadow, alpha, sky = frame
    placed_by = alpha if anchor is None else anchor
    transform = plate_transform(placed_by, place, plate.size, source, cut_allowed)
    soles = not (placed_by[-1] > 0.5).any()  # a person cut by their photo's bottom has no soles on the ground: no contact shadow
    box = landing_box(alpha, transform)
    front = in_front(plate, place.y if anchor is None else box[3] / plate.size[1], box, mattes)
    result = composite_on_plate(plate.linear, person, shadow, transform, blur, plate.focal_px if focal_px is None else focal_px,
                                sky if soles else 0.0, horizon, front)
    return result, transform, box


def write_on_plate(frame: tuple, spot: PlateSpot, png, exr, layers=None, layers_in_exr: bool = False,
                   anchor: np.ndarray | None = None) -> dict:
    """The person (``frame``: :func:`read_person`'s) composited into the plate at its spot (:class:`PlateSpot`), matched to
    the plate's defocus and grain, and written: ``png`` (8-bit sRGB, the plate's grain on the person),
    ``exr`` (linear; with ``layers_in_exr`` also the layers: the person premultiplied, the shadow as a
    multiplier, the plate) and ``layers`` (those layers in a file of their own, a batch's), all
    replaced together; ``anchor`` the matte the person is placed by when not the frame's own (a clip's first person's: every
    frame carried into the plate alike, :mod:`viewer.output.plate_clip`). No GL: a window's save writes it
    on a thread."""
    from viewer.files.imageio import atomic_paths, linear_to_srgb, write_png
    from viewer.output.layers import write_layers

    plate, place = spot.plate, spot.place
    blur, grain = feet_blur(plate.srgb, place), grain_levels(plate.srgb)
    linear = plate.linear
    result, transform, _ = composite_frame(frame, plate, place, blur, spot.horizon, anchor, spot.source, spot.cut_allowed)
    soft = enlarged(transform.scale)
    if soft:
        warnings.warn(f"{plate.source}: {soft}", stacklevel=2)
    image = {c: result.image[..., k] for k, c in enumerate("RGB")}
    parts = {**{f"person.{c}": result.person[..., k] for k, c in enumerate("RGBA")},
             **{f"shadow.{c}": result.shadow[..., k] for k, c in enumerate("RGB")},
             **{f"plate.{c}": linear[..., k] for k, c in enumerate("RGB")}}
    paths = [Path(png), Path(exr)] + ([Path(layers)] if layers is not None else [])
    with atomic_paths(*paths) as tmps:
        # zlib's level 1: written in 0.17 s at 2048 px against level 6's 0.59 s, the file 10 % larger
        write_png(tmps[0], with_grain(np.clip(linear_to_srgb(result.image), 0.0, 1.0), result.person[..., 3], grain),
                  compress_level=1)
        write_layers(tmps[1], _channels({**image, **(parts if layers_in_exr else {})}))
        if layers is not None:
            write_layers(tmps[2], _channels({**image, **parts}))
    return {"defocus_px": round(blur, 3), "grain_levels": [round(float(g), 3) for g in grain]}


def _channels(channels: dict) -> dict:
    """Half floats, as compositors' EXRs are (the values are the plate's, an 8-bit photo's, and the person's
    up to the half's largest): 0.18 s at 2048 px against 0.32 s for 32-bit floats, a third smaller."""
    return {k: np.ascontiguousarray(v, np.float16) for k, v in channels.items()}
