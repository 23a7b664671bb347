"""The window's jobs, looked at once a frame: a person opened (a photo inferred or a bundle read)
or a map's lights fitted is switched in when it is done (a new map's first frame facing its
brightest light; a new person under the lighting as the user turned it); a save's files written;
a failed one shows its line."""

from __future__ import annotations

import sys

from viewer.app import interaction as ix
from viewer.lighting.map_lights import MAP, PLATE, start_yaw


class JobPolling:
    def __init__(self, app):
        self.app = app

    def poll(self):
        self.lights_fitted()
        self.scene_opened()

    def saves_written(self):
        """Saves whose files are written: said (before the panel is drawn, so the frame that says
        "saved" also has the panel's button for the folder)."""
        for job in [j for j in self.app.saves if j.done]:
            self.app.saves.remove(job)
            self.app.recorder.saved(job)

    def _finished(self, attr: str):
        """The job in ``app.<attr>`` once it has ended (the attribute emptied): its result, or None
        (still running, none, or failed: its error shown and printed)."""
        job = getattr(self.app, attr)
        if job is None or not job.done:
            return None
        setattr(self.app, attr, None)
        if job.error:
            self.app.error, self.app.message = job.error, ""
            print(f"relight: error: {job.error}", file=sys.stderr, flush=True)
            return None
        self.app.switched = True
        return job

    def scene_opened(self):
        job = self._finished("scene_job")
        if job is None:
            return
        res = job.result
        self.app.hold_panel()
        self.app.clip.end()  # a clip's frames give way to the person opened
        self.app.session.set_scene(res.scene)  # the lighting stays as the user turned it: the same map, the same light
        self.app.view = ix.ViewState()
        self.app.frames.exposed_again()
        self.app.window.set_title(f"relight - {res.path.name}")
        how = {"inferred": "inferred now, cached for next time", "cached": "its bundle from the cache",
               "bundle": "a scene bundle"}[res.how]
        self.app.switch_message = f"opened {res.path.name} ({how}): {res.scene.output_size[0]}x{res.scene.output_size[1]}"

    def lights_fitted(self):
        job = self._finished("job")
        if job is None:
            return
        res = job.result
        self.app.hold_panel()
        new_map = job.path != self.app.env_path
        self.app.session.set_lights(res.lights, environment=res.env.pixels, new_map=new_map)
        self.app.thumbnail.prepare(res.env.pixels, res.thumbnail)
        plate = self.app.plate
        own = plate is not None and job.path == plate.light_map  # the plate's own light: in its camera's frame
        if new_map:  # the yaw a map's lights start with: its brightest light on the camera's side (the placed lights,
            # fixed to the camera, stay where they are)
            self.app.session.update(yaw=start_yaw(res.lights, PLATE if own else MAP))
        if new_map and own:
            self.app.session.update(tilt=0.0)
        if new_map and plate is not None:  # on a plate the plate sets the level: its own light's, or matched to it
            plate.light = "plate" if own else job.path.name  # what lights the person now
            self.app.session.update(exposure=plate.exposure(res.env, self.app.session.scene, self.app.session.look))
        self.app.env_path = job.path
        self.app.n_lights = len(res.lights)
        # the exposure stays (chosen when the photo opened): a night map looks like night, a bright
        # one bright; the panel's "level" button exposes for the new light
        self.app.switch_message = f"{len(res.lights)} lights ({res.how}) for {job.path.name}"
