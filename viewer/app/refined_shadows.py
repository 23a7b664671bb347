"""The refinement network's shadows in the window: run on a thread for the final engine's lights (the
soft visibility shown meanwhile) and handed to the engine when done, if its lighting is still the
engine's; a network that cannot run says why once (:attr:`RefinedShadows.error`)."""

from __future__ import annotations


class RefinedShadows:
    """The running refinement (``job``, a :class:`viewer.app.jobs.RefineJob`), the network (loaded once)
    and the last failure's words; ``wake()`` is called when a job ends (the window's)."""

    def __init__(self, wake):
        self.wake = wake
        self.refiner = None
        self.job = None
        self.error = ""

    @staticmethod
    def lights_key(eng) -> bytes:
        """What a refinement is for: the engine's lights' directions and sizes."""
        lights = eng.lights
        return lights.direction.tobytes() + lights.sigma.tobytes()

    @property
    def running(self) -> bool:
        return self.job is not None

    def start(self, eng, scene) -> bool:
        """Run the network for ``eng``'s current lights on a thread (unless this lighting's job is running,
        or another one is: its poll starts the next); False when the network cannot be loaded (said in
        :attr:`error`: the caller shows soft shadows instead)."""
        from viewer.app.jobs import RefineJob
        from viewer.photo.refinement import Refiner, light_visibility

        key = self.lights_key(eng)
        if self.job is not None and (self.job.key == key or not self.job.done):
            return True
        if self.refiner is None:
            try:
                self.refiner = Refiner()
            except Exception as exc:
                self.error = str(exc)
                return False
        hard, soft = light_visibility(eng)
        self.job = RefineJob(self.refiner, hard, soft, eng.lights.sigma, scene.depth, scene.mask, key, wake=self.wake)
        return True

    def poll(self, final, wanted: bool) -> bool:
        """Hand a finished refinement to ``final`` (the final engine) if its lighting is still the
        engine's and refined shadows are still ``wanted``; True when the frame changed."""
        job = self.job
        if job is None or not job.done:
            return False
        self.job = None
        if job.error:
            self.error = job.error
            return False
        if job.key != self.lights_key(final) or not wanted:
            return False  # the lights moved on: the next final render starts a new job
        final.set_refined_visibility(job.result)
        self.error = ""
        return True

    def stop(self):
        """A running job stopped at its next batch (a thread left inside torch aborts the exit); kept to be read."""
        if self.job is not None:
            self.job.stop()

    def forget(self):
        """The engines changed: a running job's result is for shadow maps no longer shown (stopped, let go)."""
        self.stop()
        self.job = None
