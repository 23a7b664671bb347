"""Where the person stands in the plate, and how large: ``--at X,Y`` (the feet, as fractions of the
plate's width and height) and ``--height H`` (the person's height as a fraction of the plate's).

The default follows the plate's camera. A camera ``c`` metres above the ground sees it below its
horizon; a person of ``PERSON_HEIGHT_M`` standing with their feet ``d`` below the horizon in the
picture (a fraction of its height) is ``d * PERSON_HEIGHT_M / c`` of it tall, whatever the lens or
the distance (both scale alike). ``c`` is what the people standing in the plate say
(:mod:`viewer.plate.people`), else eye height, ``CAMERA_HEIGHT_M``. The horizon is
``--horizon Y``, else the plate's own (:mod:`viewer.plate.horizon`). Without ``--at``, the feet
stand at ``DEFAULT_FEET`` of the plate's height, centred.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewer.errors import InputError
from viewer.photo.frames import person_box
from viewer.scene.camera import focal_pixels

PERSON_HEIGHT_M = 1.7
CAMERA_HEIGHT_M = 1.6  # a plate taken at eye height
DEFAULT_FEET = 0.88  # of the plate's height, from its top
LEVEL_HORIZON = 0.5  # a level camera's horizon, of the plate's height
AT_REACH = 0.5  # --at may put the feet this far beyond the plate's edges (a person cut by the frame), not farther


@dataclass(frozen=True)
class Placement:
    """The feet at (``x``, ``y``) of the plate's width and height; the person ``height`` of its height tall."""

    x: float
    y: float
    height: float


@dataclass(frozen=True)
class PlateSpot:
    """Where a person is put: the ``plate`` (:class:`viewer.plate.loader.Plate`), their ``place`` on it,
    the plate's ``horizon`` (a fraction of its height from its top: the contact shadow's ground; None:
    not known), their ``source`` (the photo or bundle named in messages) and whether their frame may
    be cut by the plate's edge (``cut_allowed``: placed by hand)."""

    plate: object
    place: Placement
    horizon: float | None = None
    source: object = None
    cut_allowed: bool = False


def placement(at: tuple[float, float] | None = None, height: float | None = None, horizon: float | None = None,
              camera_height: float | None = None) -> Placement:
    """The person's place in the plate from the options given, the rest as the module says (the plate's
    camera ``camera_height`` metres above the ground, else ``CAMERA_HEIGHT_M``); one line for what
    cannot be (feet at or above the horizon with no height given, a height of 0)."""
    check_place_options(at, horizon)
    horizon = LEVEL_HORIZON if horizon is None else float(horizon)
    x, y = (0.5, DEFAULT_FEET) if at is None else (float(at[0]), float(at[1]))
    if height is None:
        if y <= horizon:
            raise InputError(None, f"--at {x:g},{y:g}: the feet are at or above the horizon ({horizon:g} of the plate's "
                                   "height), where no ground is; give --height, or --horizon")
        height = (y - horizon) * PERSON_HEIGHT_M / (camera_height or CAMERA_HEIGHT_M)
    if not (np.isfinite(height) and 0.0 < height <= 10.0):
        raise InputError(None, f"--height must be a fraction of the plate's height in (0, 10], got {height}")
    return Placement(x, y, float(height))


def off_the_plate(place: Placement) -> str | None:
    """A line when the feet are placed outside the plate (``--at``, or dragged in the window; ``AT_REACH`` allows it:
    a person cut by its edge): where they stand, and their shadow there, are not seen. None when they are on it."""
    if 0.0 <= place.x <= 1.0 and 0.0 <= place.y <= 1.0:
        return None
    return (f"the feet are off the plate (at {place.x:.2f},{place.y:.2f} of it: "
            f"{'below its bottom edge' if place.y > 1.0 else 'above its top edge' if place.y < 0.0 else 'beyond its side'}):"
            " where they stand, and their shadow there, are not seen")


MISMATCH = 2.0  # the plate's camera this many times higher or lower than eye height, where the person stands: warned


def camera_mismatch(place: Placement, horizon: float | None = None) -> str | None:
    """A line when the placement makes the plate's camera stand far from eye height where the person
    stands (their photo was taken about there, so their perspective would not match): a person of
    ``PERSON_HEIGHT_M`` whose feet are ``d`` below the horizon and who is ``H`` tall (fractions of the
    plate's height) is seen from ``PERSON_HEIGHT_M d / H`` metres; None when it is within ``MISMATCH``
    times ``CAMERA_HEIGHT_M``."""
    horizon = LEVEL_HORIZON if horizon is None else float(horizon)
    below = place.y - horizon
    if below <= 0:
        return (f"the feet stand at or above the plate's horizon ({horizon:g}): the plate's camera looks up at the ground "
                "there, the person's photo did not; their perspective will not match (give --horizon if it is elsewhere)")
    height = PERSON_HEIGHT_M * below / place.height
    if height > MISMATCH * CAMERA_HEIGHT_M or height < CAMERA_HEIGHT_M / MISMATCH:
        fix = "a taller" if height > CAMERA_HEIGHT_M else "a shorter"  # seen from high up: the person is too small
        return (f"placed so, the plate's camera is {height:.1f} m above the ground where the person stands, the person's "
                f"photo about {CAMERA_HEIGHT_M:g} m: their perspective will not match ({fix} --height, or --horizon where "
                "the plate's horizon is)")
    return None


BODY_DEPTH_M = 0.3  # a person's depth front to back: how much nearer their front is than their back
PERSPECTIVE_TOLERANCE = 0.1  # the difference in that share of the distance (photo against plate) warned beyond


def lens_mismatch(photo_focal_35: float, frame_size: tuple[int, int], person_px: float, place: Placement,
                  plate_size: tuple[int, int], plate_focal_px: float) -> str | None:
    """A line when the person's photo saw them from a distance whose perspective the plate's would not
    give (a wide lens close up put on a plate seen from afar, or the other way round): each camera's
    distance from a person of ``PERSON_HEIGHT_M`` ``person_px`` pixels tall in their frame (of
    ``frame_size``, the photo's EXIF lens ``photo_focal_35`` mm spanning its longer side) and
    ``place.height`` of the plate tall under ``plate_focal_px``; their front is ``BODY_DEPTH_M`` /
    distance larger than their back, and a difference of ``PERSPECTIVE_TOLERANCE`` in that is warned.
    None when the photo's lens is unknown (0) or they agree."""
    if not photo_focal_35 or person_px <= 0 or place.height <= 0:
        return None
    photo_m = focal_pixels(photo_focal_35, frame_size) * PERSON_HEIGHT_M / person_px
    plate_m = plate_focal_px * PERSON_HEIGHT_M / (place.height * plate_size[1])
    if abs(BODY_DEPTH_M / photo_m - BODY_DEPTH_M / plate_m) <= PERSPECTIVE_TOLERANCE:
        return None
    near = photo_m < plate_m  # their photo was taken from nearer than the plate sees them
    how = ("near parts (hands, a foot forward) look larger than the plate's camera would show them" if near
           else "they look flatter than the plate's camera would show them")
    return (f"the person's photo saw them from about {photo_m:.1f} m ({photo_focal_35:g} mm lens), the plate from about "
            f"{plate_m:.1f} m: {how}; their perspective will not match ({'a larger' if near else 'a smaller'} --height "
            f"puts them {'nearer' if near else 'farther'}, as their photo did)")


ENLARGED = 2.0  # the person's frame shown this many times its pixels or more on the plate: warned (it looks soft)


def enlarged(scale: float | None) -> str | None:
    """A line when the person's frame is shown ``scale`` times its pixels on the plate, ``ENLARGED`` or more."""
    if scale is None or scale < ENLARGED:
        return None
    return (f"the person is shown at {scale:.1f} x their photo's pixels: they will look softer than the plate "
            "(a smaller --height, a larger photo of them, or a plate brought down to their size)")


def person_lens_mismatch(frame, place: Placement, plate) -> str | None:
    """:func:`lens_mismatch` of a scene's frame layer (its matte's height, its photo's lens) on ``plate``."""
    if frame is None:
        return None
    rows = np.flatnonzero((frame.alpha > 0.5).any(axis=1))
    if not len(rows):
        return None
    return lens_mismatch(frame.focal_35mm, (frame.width, frame.height), float(rows[-1] - rows[0] + 1), place, plate.size,
                         plate.focal_px)


def check_place_options(at: tuple[float, float] | None, horizon: float | None) -> None:
    """One line for an ``--at`` or ``--horizon`` that is no fraction of the plate (a batch checks them
    before any work; each plate then places the person on its own horizon)."""
    for name, value in [("--at", v) for v in (at or ())] + ([("--horizon", horizon)] if horizon is not None else []):
        if not np.isfinite(value):
            raise InputError(None, f"{name} must be finite, got {value}")
    if at is not None and not all(-AT_REACH <= v <= 1 + AT_REACH for v in at):
        raise InputError(None, f"--at takes the feet as fractions of the plate's width and height (0 to 1: 0.5,0.9 is the "
                               f"middle, near the bottom), got {at[0]:g},{at[1]:g}")
    if horizon is not None and not 0.0 <= horizon <= 1.0:
        raise InputError(None, f"--horizon is a fraction of the plate's height from its top (0 to 1), got {horizon:g}")


@dataclass(frozen=True)
class PlateTransform:
    """The person's frame into the plate: plate pixel = ``scale`` * frame pixel + ``offset`` (x, y)."""

    scale: float
    offset: tuple[float, float]


MIN_PERSON_PX = 8  # a person placed smaller than this many plate pixels tall is refused


def landing_box(alpha: np.ndarray, transform: PlateTransform) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1): the box of the matte ``alpha`` (above 0.5) brought into the plate by ``transform``."""
    ys, xs = np.nonzero(alpha > 0.5)
    if not len(ys):
        return 0.0, 0.0, 0.0, 0.0
    s, (ox, oy) = transform.scale, transform.offset
    return ox + s * xs.min(), oy + s * ys.min(), ox + s * (xs.max() + 1), oy + s * (ys.max() + 1)


def feet(alpha: np.ndarray, source=None, cut_allowed: bool = False) -> tuple[float, float, float, tuple]:
    """(x, y, height, box) in the frame's pixels (edges: a pixel spans [i, i + 1]): the middle of the
    person's lowest rows (their feet), the bottom of the person, the person's height (the matte above
    0.5), and its box (top, bottom, left, right). A matte that reaches the frame's bottom has no feet
    in it: one line naming ``source``, unless ``cut_allowed`` (the user gave the height)."""
    person = alpha > 0.5
    if not person.any():
        raise InputError(source, "the person's matte is empty: nothing to place on the plate")
    top, left, tall, wide = person_box(person)
    bottom = top + tall - 1
    if bottom == alpha.shape[0] - 1 and not cut_allowed:
        raise InputError(source, "the person reaches the bottom of their photo: their feet are not in it, and a plate stands "
                                 "a person on their feet; give --height to place them anyway (the cut edge on the ground)")
    low = person[max(bottom - max((bottom - top) // 50, 1), top):bottom + 1]
    xs = np.flatnonzero(low.any(axis=0))
    return float(0.5 * (xs[0] + xs[-1] + 1)), float(bottom + 1), float(tall), (top, bottom + 1, left, left + wide)


def plate_transform(alpha: np.ndarray, place: Placement, plate_size: tuple[int, int], source=None,
                    cut_allowed: bool = False) -> PlateTransform:
    """The transform that stands the person of the frame's matte ``alpha`` where ``place`` says in a
    plate of ``plate_size`` = (w, h); one line when the person would land wholly off the plate, or
    smaller than ``MIN_PERSON_PX``."""
    fx, fy, tall, (top, bottom, left, right) = feet(alpha, source, cut_allowed)
    w, h = plate_size
    if place.height * h < MIN_PERSON_PX:
        raise InputError(None, f"--height {place.height:g} makes the person {place.height * h:.2g} plate pixels tall: "
                               f"at least {MIN_PERSON_PX} are needed")
    scale = place.height * h / tall
    ox, oy = place.x * w - scale * fx, place.y * h - scale * fy
    if ox + scale * right <= 0 or oy + scale * bottom <= 0 or ox + scale * left >= w or oy + scale * top >= h:
        raise InputError(None, f"--at {place.x:g},{place.y:g} with --height {place.height:g} puts the person wholly off "
                               "the plate: give --at within [0, 1]")
    return PlateTransform(scale, (ox, oy))


def place_on_plate(plate, at: tuple[float, float] | None, height: float | None, horizon: float | None,
                   notes: list | None = None) -> tuple[Placement, float]:
    """Where the person stands on ``plate`` (:func:`placement`) on ``horizon`` or the plate's own
    (:func:`viewer.plate.horizon.plate_horizon`, said in ``notes``), as tall as the people standing in
    it would have them without ``height`` (:func:`viewer.plate.people.plate_camera_height`: the
    plate camera's height; eye height without anyone); (the placement, the horizon). Feet off the plate,
    and a placement whose camera stands far from eye height, are warned in one line each."""
    import warnings

    from viewer.plate.horizon import plate_horizon
    from viewer.plate.people import plate_camera_height

    if horizon is None:
        horizon, how = plate_horizon(plate)
        if notes is not None:
            notes.append(f"the plate's horizon at {horizon:.3f} of its height ({how})")
    camera = None
    if height is None:
        camera, people = plate_camera_height(plate, horizon, PERSON_HEIGHT_M)
        if camera is not None and notes is not None:
            notes.append(f"the plate's camera {camera:.2f} m above the ground, from {people} "
                         f"{'person' if people == 1 else 'people'} standing in it: the person sized for it")
    place = placement(at, height, horizon, camera)
    for mismatch in (off_the_plate(place), camera_mismatch(place, horizon)):
        if mismatch:
            warnings.warn(f"{plate.source}: {mismatch}", stacklevel=2)
    return place, float(horizon)
