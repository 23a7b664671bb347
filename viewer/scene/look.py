"""What the user sees, in one type: :class:`Look` (the lighting's rotation, exposure, tone map,
background, shadow mode, the shown terms and view, the light intensity and the quality preset).

The command line (``relight render``, ``demo``, ``view``), the viewer, the video writer, the GL
engine (``Engine.set_look``) and the saved state files all carry this one type, and it is
validated in one place (:meth:`Look.__post_init__`): a bad value is one clear line naming the
field, whatever path it came by. :meth:`Look.from_json` also reads the state files older versions
wrote (``shadows``/``visibility``, a plain ``exposure`` number, no ``preset``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from viewer.errors import InputError
from viewer.scene.area_lights import rotation_matrix
from viewer.shader_modes import MODES

AUTO = "auto"  # exposure: the photo's own brightness (resolved by viewer.output.render.photo_exposure)
MAX_BACKGROUND = 65504.0  # the background colour's largest value: the largest a half-float EXR holds
MAX_BACKDROP_BLUR = 30.0  # degrees (viewer.scene.backdrop.MAX_BLUR)
EXPOSURE_LIMIT = 40.0  # stops either way
TONEMAPS = MODES["TONEMAP"]
BACKGROUNDS = MODES["BACKGROUND"]
VISIBILITY_MODES = MODES["VISIBILITY"]
# What the display image shows: the relit frame, the diffuse or specular shading alone (composited
# from the same light atlas), or an inspection view of the bundle's maps or of one light's shadow.
VIEWS = ("final", "diffuse_shading", "specular_shading", "albedo", "normal", "depth", "specular", "roughness", "shadow")
PRESET_NAMES = ("interactive", "balanced", "final")  # viewer.gl.presets.PRESETS (tested equal)
MAX_INTENSITY = 1e6
MAP_CAMERA_HEIGHT_M = 1.6  # metres: an HDR map is taken from a tripod at about eye height
MAX_CAMERA_HEIGHT_M = 1000.0
MIN_CAMERA_HEIGHT_M = 0.05  # a camera lower than this sees the ground squashed past what a float holds


def _choice(name: str, value, choices) -> None:
    if not isinstance(value, str) or value not in choices:
        raise InputError(None, f"{name} must be one of {', '.join(choices)}, got {value!r}")


def _finite(name: str, value, low: float, high: float, unit: str = "") -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
            or not math.isfinite(float(value)) or not low <= float(value) <= high:
        raise InputError(None, f"{name} must be a finite number in [{low:g}, {high:g}]{unit}, got {value!r}")


@dataclass(frozen=True)
class Look:
    yaw: float = 0.0  # degrees: the lighting (and the map behind) turned about the vertical axis
    tilt: float = 0.0  # degrees, about the camera's horizontal axis
    exposure: float | str = 0.0  # stops, or "auto" (a photo keeps its own brightness; 0 until resolved)
    tonemap: str = "neutral"  # TONEMAPS: the photo's tones kept, highlights rolled off with their hue (tonemap.glsl)
    background: str = "environment"  # environment | photo | color | transparent
    background_color: tuple = (0.18, 0.18, 0.18)  # linear RGB of the "color" background
    shadows: str = "soft"  # soft (EngineOptions.soft: PCSS or CSM) | refined (network) | hard (shadow map) | none
    diffuse: bool = True  # the diffuse term shown
    specular: bool = True  # the specular term shown
    skin: bool = True  # light scattered under the skin (a photo's skin map; viewer/gl/skin_pass.py)
    view: str = "final"  # VIEWS
    light: int = 0  # the selected light (its shadow in the "shadow" view)
    intensity: float = 1.0  # scales the map's lights
    placed_intensity: float = 1.0  # scales your lights (viewer.lighting.placed_lights), apart from the map's
    preset: str = "balanced"  # quality preset (viewer.gl.presets)
    compare: float = 0.0  # before / after: the share of the frame, from the left, showing the original photo (0: off)
    ground: bool | str = AUTO  # the person's shadow on a ground plane at the feet, over the background (a shadow
    # catcher); "auto": shown when the feet are in the frame and the map is behind the person (ground_shown)
    backdrop_blur: float | str = AUTO  # degrees: the map behind the person blurred like a defocused background;
    # "auto": as much as the photo's own background is (viewer.scene.backdrop), 0 for a scene without a photo
    camera_height: float = 0.0  # metres above the ground the map behind is seen from; the map's ground projected
    # on a plane that far below (envmap.glsl); 0: a clip's camera as read from its person (viewer.output.clip_frames),
    # else the map as it was taken (MAP_CAMERA_HEIGHT_M gives that on a clip too)

    def __post_init__(self):
        _finite("yaw", self.yaw, -1e6, 1e6, " degrees")
        _finite("tilt", self.tilt, -1e6, 1e6, " degrees")
        if self.exposure != AUTO:
            _finite("exposure", self.exposure, -EXPOSURE_LIMIT, EXPOSURE_LIMIT, " stops (or auto)")
        _choice("tone map", self.tonemap, TONEMAPS)
        _choice("background", self.background, BACKGROUNDS)
        try:
            if any(isinstance(c, (bool, np.bool_)) for c in self.background_color):
                raise TypeError("booleans are not colours")
            color = np.asarray(self.background_color, dtype=np.float64)
        except (TypeError, ValueError):
            color = np.zeros(0)
        if color.shape != (3,) or not np.all(np.isfinite(color)) or np.any(color < 0) or np.any(color > MAX_BACKGROUND):
            raise InputError(None, f"background colour must be three values in [0, {MAX_BACKGROUND:g}] (linear; 1 is white), "
                                   f"got {self.background_color!r}")
        object.__setattr__(self, "background_color", tuple(float(c) for c in color))
        _choice("shadows", self.shadows, VISIBILITY_MODES)
        for name in ("diffuse", "specular", "skin"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise InputError(None, f"{name} must be true or false, got {getattr(self, name)!r}")
        if not isinstance(self.ground, (bool, np.bool_)) and self.ground != AUTO:
            raise InputError(None, f"ground must be true or false (or auto), got {self.ground!r}")
        if self.backdrop_blur != AUTO:
            _finite("backdrop blur", self.backdrop_blur, 0.0, MAX_BACKDROP_BLUR, " degrees (or auto)")
        _finite("camera height", self.camera_height, 0.0, MAX_CAMERA_HEIGHT_M, " metres (0: a clip's own, else the map's)")
        if 0.0 < self.camera_height < MIN_CAMERA_HEIGHT_M:
            raise InputError(None, f"camera height must be 0 (a clip's own, else the map's) or at least "
                                   f"{MIN_CAMERA_HEIGHT_M:g} metres, got {self.camera_height!r}")
        _choice("view", self.view, VIEWS)
        if isinstance(self.light, bool) or not (isinstance(self.light, (int, np.integer)) and self.light >= 0):
            raise InputError(None, f"light must be an index >= 0 (the selected light), got {self.light!r}")
        _finite("intensity", self.intensity, 0.0, MAX_INTENSITY)
        _finite("your lights' intensity", self.placed_intensity, 0.0, MAX_INTENSITY)
        _choice("preset", self.preset, PRESET_NAMES)
        _finite("compare", self.compare, 0.0, 1.0, " (the share of the frame showing the photo)")

    @property
    def environment_rotation(self) -> np.ndarray:
        """3x3: camera directions to the turned map's directions (the background's lookup)."""
        return rotation_matrix(self.yaw, self.tilt).T

    def seen_from(self, height: float) -> float:
        """The camera height the map's ground is seen from with a clip's ``height`` read (0: none): this
        look's own when it sets one (a ``--look`` file), else the clip's."""
        return self.camera_height or height

    @property
    def ground_squash(self) -> float:
        """How the map's ground is seen from :attr:`camera_height` (``shaders/envmap.glsl: ground_projected``):
        the map's camera height over it; 1 (the map as taken) at 0."""
        return MAP_CAMERA_HEIGHT_M / float(self.camera_height) if self.camera_height > 0 else 1.0

    def ground_shown(self, feet: bool, background: str) -> bool:
        """Whether the ground shadow shows: as set, or ("auto") when the person's ``feet`` are in
        the frame and the ``background`` shown is the environment map."""
        return bool(self.ground) if self.ground != AUTO else bool(feet and background == "environment")

    @property
    def exposure_stops(self) -> float:
        """The exposure to display with: 0 stops while "auto" is not resolved yet."""
        return 0.0 if self.exposure == AUTO else float(self.exposure)

    def turned(self, lights, placed=None):
        """The lights this look renders (:class:`viewer.scene.area_lights.AreaLights`): the map's
        ``lights`` turned by its yaw and tilt and scaled by its intensity, then the ``placed`` ones,
        fixed to the camera, scaled by its placed intensity."""
        out = lights.rotated(self.yaw, self.tilt).scaled(self.intensity)
        return out if placed is None else out.followed_by(placed.scaled(self.placed_intensity))

    def on_frame(self, turn: tuple[float, float] = (0.0, 0.0), height: float = 0.0) -> Look:
        """The look a frame renders with, the one rule for every frame (a clip's, the window's, a
        frame prepared ahead): the map turned on by ``turn`` (yaw, tilt) degrees (the clip's turn and
        its camera's; the placed lights are not turned, :meth:`turned`) and the ground seen from
        ``height`` metres (unless the look sets its own, :meth:`seen_from`). Itself when nothing moves."""
        yaw, tilt = turn
        height = self.seen_from(height)
        if not (yaw or tilt or height != self.camera_height):
            return self
        return replace(self, yaw=self.yaw + yaw, tilt=self.tilt + tilt, camera_height=height)

    def fitted(self, n_lights: int) -> Look:
        """This look for a set of ``n_lights`` lights: a selected light past the set (a look saved
        with more lights) becomes light 0, and its shadow view the relit image."""
        if self.light < n_lights:
            return self
        return replace(self, light=0, view="final" if self.view == "shadow" else self.view)

    def replace(self, **changes) -> Look:
        return replace(self, **changes)

    def to_json(self) -> dict:
        out = asdict(self)
        out["background_color"] = list(self.background_color)
        return out

    @classmethod
    def from_json(cls, data, where=None, base: Look | None = None) -> Look:
        """A look saved by :meth:`to_json`, or by an older version (``visibility`` for ``shadows``), or
        a part of one (the fields it lacks are ``base``'s, the defaults when None); unknown keys are
        ignored, a bad value is one line naming ``where``."""
        if not isinstance(data, dict):
            raise InputError(where, f"the look must be a JSON object, got {type(data).__name__}")
        data = dict(data)
        if "visibility" in data and "shadows" not in data:
            data["shadows"] = data.pop("visibility")
        known = {f.name for f in fields(cls)}
        try:
            return cls(**{**(asdict(base) if base is not None else {}), **{k: v for k, v in data.items() if k in known}})
        except InputError as exc:
            raise InputError(where, exc.problem) from None
