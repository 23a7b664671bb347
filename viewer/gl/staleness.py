"""What is out of date. Each pass names the inputs that make its result stale (``inputs``, and
``whole_inputs`` for a frame pass that then redraws its whole image, not only the mask's box); a
change marks the passes that read it, and a pass that ran counts as a change in turn, which is how a
new direction reaches the composite. docs/engine.md's cache table is these declarations."""

from __future__ import annotations


class Staleness:
    """Per-light passes keep their stale names on each light (``Light.stale``); frame passes here."""

    def __init__(self, light_passes, frame_passes):
        self.light_passes, self.frame_passes = tuple(light_passes), tuple(frame_passes)
        self.frame = {p.name: "all" for p in self.frame_passes}  # None, "box" (the mask's / matte's) or "all"
        self.changes = 0  # how many changes so far: work left part-way is good only while this stays the same

    def changed(self, what: str, lights=()):
        """``what`` changed (an input, or the output of a pass that ran): the passes that read it
        are stale: per-light passes for ``lights``, frame passes over their box or as a whole."""
        self.changes += 1
        for p in self.light_passes:
            if what in p.inputs:
                for l in lights:
                    l.stale.add(p.name)
        for p in self.frame_passes:
            if what in getattr(p, "whole_inputs", ()):
                self.frame[p.name] = "all"
            elif what in p.inputs:
                self.frame[p.name] = self.frame[p.name] or "box"

    def ran(self, p, lights=()):
        """Pass ``p`` brought its result up to date (for ``lights``): its output changed."""
        for l in lights:
            l.stale.discard(p.name)
        if p.name in self.frame:
            self.frame[p.name] = None
        self.changed(p.name, lights)
