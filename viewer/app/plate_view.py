"""The plate in the window: the person composited into a background photo as ``relight
render --plate`` composites them (:func:`viewer.output.plate_composite.composite_on_plate`: the same
code), on a copy of the plate at most ``VIEW_LONGER`` pixels long; dragging the person moves where
their feet stand, the wheel on them scales them about their feet. The plate's own pixels, its defocus where
the feet stand and its placement are this object's; the person and their shadow are the engine's
frame, read back when it changes (not when only the placement does). S writes the composite at the
plate's full size (:func:`viewer.output.plate_render.write_on_plate`, on a thread); a recording's
frames are the composite (:meth:`PlateView.picture`). A clip's person is placed once, by the matte of
its first frame with them in it (:func:`clip_anchor`), and every frame carried alike, as ``relight
render CLIP --plate`` does (:mod:`viewer.output.plate_clip`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import linear_to_srgb
from viewer.output.plate_render import composite_frame, read_person
from viewer.plate.loader import Plate
from viewer.plate.match import feet_blur
from viewer.plate.placement import Placement, camera_mismatch, enlarged, off_the_plate, person_lens_mismatch, plate_transform
from viewer.scene.look import Look

VIEW_LONGER = 1600  # the plate's copy the window composites on: its longer side at most (S writes the whole plate)
SCALE_PER_NOTCH = 1.06  # the person's height per wheel notch
HEIGHT_RANGE = (0.02, 3.0)  # of the plate's height, as the wheel leaves it
MIN_BELOW = 0.01  # of the plate's height: the least distance below the horizon the person is scaled by


def srgb8(linear: np.ndarray) -> np.ndarray:
    """(..., 3) linear (clipped to [0, 1]) as 8-bit sRGB, as the display shows it."""
    return (np.clip(linear_to_srgb(np.nan_to_num(linear, nan=0.0)), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def plate_setting(path, at: tuple[float, float] | None, height: float | None, horizon: float | None, own_light,
                  notes: list, anchor=None, front=None) -> tuple[tuple, Path | None]:
    """A photo opened as a plate: (the plate, where the person stands on it, its horizon, what lights the
    person: "plate" or the name of ``own_light``, the plate's light as a map file, ``anchor`` (a clip's
    first person's matte, which places every frame): :class:`PlateView`'s arguments), and that map file
    to open as any map's, None where ``own_light`` (a map or a light file) lights the person. One line
    when it cannot be a plate (:func:`viewer.plate.loader.read_plate`) or the person cannot stand
    where asked (:func:`viewer.plate.placement.plate_transform`). ``front``: the user's mask of what stands in
    front of the person (``--front``, :mod:`viewer.plate.front_mask`)."""
    from viewer.lighting.lightfit.cache import cache_dir
    from viewer.plate.environment import plate_light_file
    from viewer.plate.loader import read_plate
    from viewer.plate.placement import place_on_plate

    plate = read_plate(path, notes, front)
    place, horizon = place_on_plate(plate, at, height, horizon, notes)
    if anchor is not None:  # a clip's person placed once: one line before the window if they cannot stand there
        plate_transform(anchor, place, plate.within(VIEW_LONGER).size, cut_allowed=True)
    light_map = plate_light_file(plate, cache_dir() / "plates", notes, horizon)
    return (plate, place, horizon, Path(own_light).name if own_light else "plate", light_map, anchor), None if own_light else light_map


def clip_anchor(timeline) -> np.ndarray:
    """The matte a clip's person is placed on a plate by: its first frame with the person's (as
    :class:`viewer.output.plate_clip.PlatePictures` places them)."""
    first = timeline.frames.people[0]
    scene = timeline.frames.scene(first, timeline.sizes)
    return scene.frame.alpha if scene.frame is not None else scene.mask.astype(np.float32)


class PlateView:
    """A plate shown in the window with the person in it: its texture (the composite, sRGB, the
    plate's copy's size), where the person stands (:attr:`place`) and the plate's horizon."""

    def __init__(self, ctx, plate: Plate, place: Placement, horizon: float, light: str, light_map: Path, anchor=None):
        import moderngl

        self.plate, self.place, self.horizon = plate, place, float(horizon)
        # a clip's: the matte of its first frame with the person, which places every frame (they walk across
        # the plate as across their frame, :mod:`viewer.output.plate_clip`); a photo's own frame places it
        self.anchor = anchor
        self.light = light  # "plate": lit by the plate's own light; else the name of the map that lights the person
        self.light_map = Path(light_map)  # the plate's light as a map file (viewer.plate.environment.plate_light_file)
        self._light_env = None  # that map, read when a map of the user's is to be exposed to it
        self.shown = plate.within(VIEW_LONGER)  # the copy composited on
        self.size, self.linear = self.shown.size, self.shown.linear
        self._mattes: dict = {}  # the mattes of the plate's people found standing in front, by index
        self.texture = ctx.texture(self.size, 3, dtype="f1")
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._srgb = srgb8(self.linear)  # what the texture shows: the plate alone, then with the person
        self.texture.write(self._srgb.tobytes())
        self._person = None  # (key, the person premultiplied and exposed, the shadow share, the matte) of the engine's frame
        self._shown = None  # (person key, place, blur) the texture shows
        self._blur: tuple[Placement, float] | None = None  # the plate's defocus (copy's pixels) where the feet stand
        self.box: tuple[float, float, float, float] | None = None  # the person's box in the copy's pixels (x0, y0, x1, y1)
        self._frame = None  # (the transform shown, the person's frame size (w, h)): where a point of the plate is in it
        self.error = ""  # why the last placement asked for could not be shown (the one before stays)
        # the look's fields the plate changed, and whether the exposure was automatic: back when it is removed
        self.restore = {"background": Look().background, "ground": Look().ground, "auto": True, "map": None}
        self.notes: list[str] = []  # what reading and placing it said (its lens, horizon, camera height)

    def exposure(self, light, scene, look) -> float:
        """The person's exposure on this plate under ``light`` (a map, or a light file's lights) turned by
        ``look``: 0 (the plate's units) under the plate's own light, else the stops that give them the
        plate's light's diffuse level (:func:`viewer.plate.exposure.person_exposure`)."""
        from viewer.lighting.envmap import load_envmap
        from viewer.plate.exposure import person_exposure

        if self.light == "plate":
            return 0.0
        if self._light_env is None:
            self._light_env = load_envmap(self.light_map)
        return person_exposure(self._light_env, light, scene, look)

    def mismatches(self, scene) -> list[str]:
        """What does not match the person's photo where they stand: feet off the plate, the plate camera's height
        (:func:`camera_mismatch`), its distance (:func:`person_lens_mismatch`, ``scene``'s photo's lens)
        and their frame's pixels enlarged (:func:`enlarged`)."""
        scale = None if self._frame is None else self._frame[0].scale * self.plate.size[0] / self.size[0]
        return [line for line in (off_the_plate(self.place), camera_mismatch(self.place, self.horizon),
                                  person_lens_mismatch(scene.frame, self.place, self.plate),
                                  enlarged(scale)) if line]

    def blur(self, settled: bool) -> float:
        """The plate's defocus where the feet stand, in the copy's pixels: measured again once the
        person is let go (``settled``), the last one's meanwhile."""
        if self._blur is None or (settled and self._blur[0] != self.place):
            k = self.size[0] / self.plate.size[0]
            self._blur = (self.place, feet_blur(self.plate.srgb, self.place) * k)
        return self._blur[1]

    def frame_texture(self, eng, key, settled: bool = True, person: bool = True):
        """The texture showing ``eng``'s person (its last complete frame, whose state is ``key``) in
        the plate where :attr:`place` says: composited again when either changed; the plate alone
        without ``person`` (a clip's frame with no one in it)."""
        self._composite(eng, key, settled, person)
        return self.texture

    def picture(self, eng, key, person: bool = True) -> np.ndarray:
        """(H, W, 3) uint8 sRGB at the copy's size: what :meth:`frame_texture` shows (a recording's frame)."""
        return self._composite(eng, key, True, person).copy()

    def _composite(self, eng, key, settled: bool, shows_person: bool = True) -> np.ndarray:
        """The plate with ``eng``'s person in it, sRGB uint8 (and in :attr:`texture`), made again when the
        person's frame or where they stand changed; the plate alone until the person's first frame, and
        without ``shows_person``."""
        if not shows_person:
            if self._shown is not None:
                self._srgb, self._shown = srgb8(self.linear), None
                self.box = self._frame = None  # no one to drag, scale or aim at
                self.texture.write(self._srgb.tobytes())
            return self._srgb
        # (the engine itself, not its id: a released engine's id can be a new one's)
        if eng.complete and (self._person is None or self._person[0][0] is not eng or self._person[0][1] != key):
            self._person = ((eng, key), *read_person(eng))
        if self._person is None:
            return self._srgb  # the plate alone until the person's first frame is complete
        blur = self.blur(settled)
        shown = (self._person[0], self.place, blur)
        if shown != self._shown:
            frame = self._person[1:]  # (the person, the shadow, the matte, the sky's share)
            try:
                result, transform, self.box = composite_frame(frame, self.shown, self.place, blur, self.horizon, self.anchor,
                                                              cut_allowed=True, mattes=self._mattes,
                                                              focal_px=self.plate.focal_at(self.size))
            except InputError as exc:  # wholly off the plate, too small: the placement before stays
                self.error = str(exc)
                return self._srgb
            self.error = ""
            alpha = frame[2]
            self._srgb = srgb8(result.image)
            self.texture.write(self._srgb.tobytes())
            self._frame = (transform, (alpha.shape[1], alpha.shape[0]))
            self._shown = shown
        return self._srgb

    def unanchor(self):
        """No longer a clip's: the person is placed by their own frame again."""
        self.anchor, self._shown = None, None

    def box_fractions(self) -> list[float] | None:
        """The person's box on the plate (x0, y0, x1, y1) as fractions of its width and height, or None."""
        if self.box is None:
            return None
        w, h = self.size
        return [self.box[0] / w, self.box[1] / h, self.box[2] / w, self.box[3] / h]

    def holds(self, u: float, v: float) -> bool:
        """Whether the point (``u``, ``v``), fractions of the plate, is on the person's box."""
        if self.box is None:
            return False
        x, y = u * self.size[0], v * self.size[1]
        x0, y0, x1, y1 = self.box
        return x0 <= x <= x1 and y0 <= y <= y1

    def frame_point(self, u: float, v: float) -> tuple[float, float] | None:
        """Where the point (``u``, ``v``) of the plate (fractions) is in the person's frame (fractions of
        it; a click that aims a light), or None off the frame."""
        if self._frame is None:
            return None
        (transform, (fw, fh)) = self._frame
        a = (u * self.size[0] - transform.offset[0]) / transform.scale / fw
        b = (v * self.size[1] - transform.offset[1]) / transform.scale / fh
        return (a, b) if 0.0 <= a < 1.0 and 0.0 <= b < 1.0 else None

    def moved(self, du: float, dv: float):
        """The feet moved by (``du``, ``dv``), fractions of the plate (kept where --at may put them); on the
        ground below the horizon the person grows as they come nearer and shrinks as they go (their height
        in proportion to the feet's distance below the horizon, as the plate's camera would see them)."""
        from viewer.plate.placement import AT_REACH

        x = min(max(self.place.x + du, -AT_REACH), 1.0 + AT_REACH)
        y = min(max(self.place.y + dv, -AT_REACH), 1.0 + AT_REACH)
        # (feet at or above the horizon count as just below it: a drag there and back gives the height back)
        before, after = max(self.place.y - self.horizon, MIN_BELOW), max(y - self.horizon, MIN_BELOW)
        height = min(max(self.place.height * after / before, HEIGHT_RANGE[0]), HEIGHT_RANGE[1])
        self._place(replace(self.place, x=x, y=y, height=height))

    def scaled(self, notches: float):
        """The person larger (or smaller) by the wheel, about their feet."""
        height = self.place.height * SCALE_PER_NOTCH ** float(notches)
        self._place(replace(self.place, height=min(max(height, HEIGHT_RANGE[0]), HEIGHT_RANGE[1])))

    def _place(self, place: Placement):
        """``place`` taken where the person's frame can stand there (not wholly off the plate, not too
        small: :func:`plate_transform`); else the place before stays, and :attr:`error` says why."""
        placed_by = self.anchor if self.anchor is not None else None if self._person is None else self._person[3]
        if placed_by is not None:
            try:
                plate_transform(placed_by, place, self.size, cut_allowed=True)
            except InputError as exc:
                self.error = str(exc)
                return
        self.error = ""
        self.place = place

    def to_json(self) -> dict:
        return {"source": self.plate.source, "at": [round(self.place.x, 6), round(self.place.y, 6)],
                "height": round(self.place.height, 6), "horizon": round(self.horizon, 6), "light": self.light,
                "size": list(self.plate.size)}

    def release(self):
        self.texture.release()
