"""What the viewer does when the user asks: save the frame or the rig, record, open a map, a
person or a rig, aim a placed light, compare before / after, change the quality preset. Each
action reads and changes the window's state (:class:`viewer.app.viewer_app.ViewerApp`) and says what it
did in its message line; the frame loop and the panel call them."""

from __future__ import annotations

import sys
from pathlib import Path

from viewer.app import interaction as ix
from viewer.app.jobs import LightJob, SceneJob
from viewer.lighting.placed_lights import PlacedLight, level
from viewer.scene.bundle import PHOTO_SUFFIXES


class Actions:
    def __init__(self, app):
        self.app = app
        self.last_compare = 0.5  # where B puts the before / after split

    def report(self, what: str, exc: Exception):
        """An error in an action: shown in the panel and printed; the viewer goes on."""
        self.app.error = f"{what}: {exc}"
        print(f"relight: error: {self.app.error}", file=sys.stderr, flush=True)

    def level_exposure(self):
        """The exposure that keeps the photo's brightness under the lights now (what a photo gets
        when it opens): a new map keeps the exposure it had until this is asked. On a plate: the
        plate's level (:meth:`viewer.app.plate_view.PlateView.exposure`)."""
        s = self.app.session
        if self.app.plate is not None:
            from viewer.lighting.envmap import EnvMap

            s.update(exposure=self.app.plate.exposure(EnvMap(s.environment) if s.environment is not None else s.lights, s.scene, s.look))
            self.app.message = f"exposure levelled to the plate: {s.look.exposure_stops:+.2f} stops"
            return
        self.app.frames.apply_auto_exposure()
        self.app.message = f"exposure levelled to the photo: {self.app.session.look.exposure_stops:+.2f} stops"

    def open_map(self, path: Path, n: int | None = None):
        if self.app.job is not None:
            self.app.message = "still fitting the previous map"
            return
        self.app.error = ""
        self.app.message = f"lights for {Path(path).name}; the window stays live meanwhile"
        self.app.job = LightJob(path, n or self.app.n_lights, self.app.config.method, wake=self.app.window.wake,
                            worker=self.app.workers["lights"])

    def open_scene(self, path: Path):
        """Another person: a photo (inferred in a child process, or from the cache) or a scene
        bundle, read on a thread; the window shows it when its maps are ready (:meth:`_poll_scene_job`)."""
        if self.app.scene_job is not None:
            self.app.message = f"still opening {self.app.scene_job.path.name}"
            return
        self.app.error = ""
        self.app.message = f"opening {path.name}; the window stays live meanwhile"
        self.app.scene_job = SceneJob(path, self.app.config.max_size, self.app.config.device, wake=self.app.window.wake,
                                  worker=self.app.workers["photo"])

    def open_file(self, path: Path):
        """A file dropped on the window or chosen in its browser: a photo or a scene bundle (its
        folder or its scene.json) becomes the person shown; an environment map is fitted and
        switched to with its lights; a rig's lights are placed. Anything else is one line saying
        what the window opens."""
        from viewer.app.files import is_bundle
        from viewer.errors import InputError
        from viewer.files.kinds import kind_of, wrong_kind
        from viewer.lighting.placed_lights import load_rig

        suffix = path.suffix.lower()
        if self.app.panel.plate_next and suffix in PHOTO_SUFFIXES:  # asked for: a background, not a person
            self.app.panel.plate_next = False
            self.open_plate(path)
        elif is_bundle(path):
            self.open_scene(path)
        elif path.name == "scene.json":
            self.open_scene(path.parent)
        elif suffix in PHOTO_SUFFIXES:
            self.open_scene(path)
        elif suffix in (".hdr", ".exr"):
            self.open_map(path)
        elif suffix == ".json" and kind_of(path) not in ("rig", None):  # a light file, a saved look...
            self.app.error = str(wrong_kind(path, "a rig"))
        elif suffix == ".json":
            try:
                self.app.session.set_placed(load_rig(path))
            except InputError as exc:
                self.app.error = str(exc)
                return
            self.app.message = f"{len(self.app.session.placed)} placed lights from {path.name}"
        else:
            self.app.error = (f"{path}: the window opens photos ({', '.join(PHOTO_SUFFIXES)}), scene bundles (a folder "
                          "with scene.json), environment maps (.hdr, .exr) and rigs (.json)")

    def aim_at(self, x: float, y: float):
        """Aim the placed light being aimed so that it faces the person's surface under the image
        point (x, y) head-on (its direction: the normal there); on a plate, the person's point there."""
        sc = self.app.session.scene
        rect = self.app.image_rect()
        if self.app.plate is not None:
            at = self.app.plate.frame_point((x - rect[0]) / rect[2], (y - rect[1]) / rect[3])
            px = None if at is None else (min(int(at[0] * sc.width), sc.width - 1), min(int(at[1] * sc.height), sc.height - 1))
        else:
            px = ix.image_pixel((x, y), rect, (sc.width, sc.height))
        if px is None or not sc.mask[px[1], px[0]]:
            self.app.aiming = None
            self.app.message = "not aimed: click on the person"
            return
        self.aim_direction(sc.normal[px[1], px[0]], f"the person's pixel {px[0]}, {px[1]}")

    def aim_direction(self, direction, where: str = "the map's point clicked"):
        """The placed light being aimed turned to come from ``direction`` (camera space); with none
        being aimed, a new light from there."""
        s = self.app.session
        j, self.app.aiming = self.app.aiming, None
        placed = list(s.placed)
        if j is None or j >= len(placed):
            placed.append(PlacedLight.aimed(direction, intensity=self.placed_level()))
            j, verb = len(placed) - 1, "added at"
        else:
            p = placed[j]
            placed[j] = PlacedLight.aimed(direction, size=p.size, intensity=p.intensity, kelvin=p.kelvin)
            verb = "aimed at"
        s.set_placed(placed)
        self.app.message = f"light {len(s.base_lights) + j} {verb} {where}"

    def placed_on_plate(self):
        """The person let go on the plate (or scaled): where they stand said, with the camera's warning."""
        p = self.app.plate
        self.app.message = "; ".join([f"the feet at {p.place.x:.3f},{p.place.y:.3f}, {p.place.height:.3f} of the plate tall",
                                      *p.mismatches(self.app.session.scene)])

    def open_plate(self, path: Path):
        """A photo opened as the plate: read, the person placed on its ground (the default place on
        its own horizon), lit by its light (a map made from it, fitted as any map's); one line when it
        cannot be a plate (the plate before, if any, stays)."""
        from viewer.app.plate_view import PlateView, clip_anchor, plate_setting

        if self.app.job is not None:
            self.app.message = "still fitting the previous map: open the plate once it is done"
            return
        notes: list = []
        try:
            anchor = clip_anchor(self.app.timeline) if self.app.timeline is not None else None  # a clip: placed by its first person
            setting, light_map = plate_setting(path, None, None, None, None, notes, anchor)
        except Exception as exc:  # not a photo, a panorama, too large: said, nothing changes
            self.report(f"{Path(path).name} cannot be a plate", exc)
            return
        if self.app.recording is not None:  # its frames are the plate's size: it ends with the frames it has
            self.app.recorder.finish_recording(stopped=True)
        s = self.app.session
        restore = {"background": s.look.background, "ground": s.look.ground, "auto": self.app.auto_exposure,
                   "map": self.app.env_path}
        if self.app.plate is not None:
            restore = self.app.plate.restore  # the look before the first plate
            self.app.plate.release()
        self.app.plate = PlateView(self.app.window.ctx, *setting)
        self.app.plate.restore, self.app.plate.notes = restore, notes
        for note in notes:
            print(f"note: {note}", flush=True)
        self.app.view = ix.ViewState()
        s.update(background="transparent", ground=True, exposure=0.0, yaw=0.0, tilt=0.0)
        self.app.auto_exposure = False  # the person is exposed in the plate's units
        self.open_map(light_map)
        self.app.message = f"plate {Path(path).name}: " + "; ".join(notes + ["drag the person to move them, the wheel on them scales them"])

    def remove_plate(self):
        """The plate gone: the person shown in their frame again, under the lights they have."""
        plate = self.app.plate
        if plate is not None:
            if self.app.recording is not None:  # its frames are the plate's: it ends with the frames it has
                self.app.recorder.finish_recording(stopped=True)
            plate.release()
            self.app.plate = None
            self.app.view = ix.ViewState()
            self.app.session.update(background=plate.restore["background"], ground=plate.restore["ground"])
            self.app.auto_exposure = plate.restore["auto"]
            if self.app.auto_exposure:  # the photo's own brightness again
                self.app.frames.apply_auto_exposure()
            self.app.message = "the plate removed"
            if plate.restore["map"] is not None and plate.restore["map"] != self.app.env_path:  # the map before it, back
                self.open_map(plate.restore["map"])

    def start_aiming(self, j: int):
        """The next click on the person or the map aims placed light ``j``."""
        self.app.aiming = j
        self.app.message = f"click on the person or the map: light {len(self.app.session.base_lights) + j} will face that point"

    def use_rig(self, name: str):
        """The placed lights of rig ``name`` in place of the user's (undoable)."""
        from viewer.lighting.placed_lights import rig

        s = self.app.session
        replaced = len(s.placed)
        s.set_placed(rig(name, self.placed_level()))
        self.app.message = (f"rig {name}: {len(s.placed)} lights"
                            + (f" in place of your {replaced} (Ctrl+Z brings them back)" if replaced else ""))

    def refit(self, n: int):
        """The map's lights fitted again at ``n`` lights (the panel's count slider let go, a preset's count)."""
        self.app.n_lights = n
        self.open_map(self.app.env_path, n)

    def placed_level(self) -> float:
        """A new placed light's intensity: the map's level (viewer.lighting.placed_lights.level)."""
        return level(self.app.session.base_lights)

    def save_rig(self):
        from viewer.lighting.placed_lights import save_rig

        try:
            self.app.config.out_dir.mkdir(parents=True, exist_ok=True)
            stem = self.app.recorder.capture_stem()  # a name no file has
            path = save_rig(stem.with_name(f"rig-{stem.name.removeprefix('relight-')}.json"), self.app.session.placed)
        except OSError as exc:
            self.report("saving the rig failed", exc)
            return
        self.app.message = f"saved the rig: {path.name} (relight view --rig {path.name})"

    def toggle_compare(self):
        """Before / after: the original photo left of a split (at the last position, half the frame
        at first), or the relit frame alone again."""
        if self.app.session.scene.frame is None:
            self.app.message = "before / after needs a photo: this scene has no original to show"
            return
        look = self.app.session.look
        if look.compare > 0.0:
            self.last_compare = look.compare
        self.app.session.update(compare=0.0 if look.compare > 0.0 else self.last_compare)

    def set_preset(self, name: str):
        """A quality preset: its engine options now, its number of lights refitted (cached) when the
        lights came from a map."""
        from viewer.gl.presets import preset

        p = preset(name)
        self.app.preset = name
        self.app.session.set_options(p.options)
        if p.lights != len(self.app.session.sigma) and self.app.env_path is not None:
            self.refit(p.lights)
        self.app.message = f"preset {name}: {p.summary}"
