"""What a clip bundle's frame index stands for when it is relit: which frame shows (a lost frame shows
the one before), the shot's first frame with a person (what a shot holds is read there), the lens the
map behind is seen through, and how far the camera turned since its shot began. Shared by the relit
MP4 (:mod:`viewer.output.clip_render`) and the window's timeline (:mod:`viewer.app.timeline`), so
both show a frame the same way."""

from __future__ import annotations

import copy

from viewer.errors import InputError
from viewer.files.imageio import read_json
from viewer.photo.camera_motion import turned
from viewer.photo.frames import output_frame
from viewer.scene.camera import focal_pixels
from viewer.scene.clip_bundle import ClipBundle


def shows_filmed_frame(engine) -> bool:
    """Whether a frame without the person shows the frame as filmed (the photo background, as
    ``engine``'s look resolves it: asked for, or the scene's own with no map), not the new
    background alone: the relit MP4 and the window's timeline decide it here alike."""
    return engine.looks.resolved(engine.look).background == "photo"


MIN_BELOW = 0.02  # the feet's tangent down from the horizon below which a camera's height is not read (at the horizon)


def below_horizon(x: float, row: float, size: tuple[int, int], tilt: float, focal_px: float) -> float:
    """The tangent of the angle below the horizon (negative: above it) of the ray through pixel position
    (``x``, ``row``) of a frame of ``size`` (w, h), seen through a lens of ``focal_px`` tilted ``tilt`` degrees
    down (as ``Look.tilt`` turns the map behind)."""
    import numpy as np

    from viewer.scene.area_lights import rotation_matrix

    w, h = size
    d = np.array([(x - 0.5 * w) / focal_px, -(row - 0.5 * h) / focal_px, -1.0]) @ rotation_matrix(0.0, tilt)
    return float(-d[1] / np.hypot(d[0], d[2]))


def person_seen_from(mask, pitch: float, focal_px: float, face_box: tuple | None = None) -> float:
    """Metres above the ground a camera tilted ``pitch`` degrees (down: positive, as ``Look.tilt``) with focal length
    ``focal_px`` (pixels of ``mask``, centred) stood to see a person of ``PERSON_HEIGHT_M`` as ``mask``
    (H, W) bool shows them standing (:meth:`ClipFrames.camera_height`): their top is the mask's over their face
    (``face_box``, fractions of the frame: hands raised above the shoulders do not make them taller), else the
    mask's. 0 when their feet are not in it (:func:`viewer.scene.ground.contacts`), the frame's top edge cuts
    them, or the reading is out of the range a plate's people are believed in
    (:data:`viewer.plate.people.CAMERA_RANGE`). A child, or someone sitting, reads a camera too high."""
    import numpy as np

    from viewer.plate.people import CAMERA_RANGE
    from viewer.plate.placement import PERSON_HEIGHT_M
    from viewer.scene.ground import contacts

    feet = contacts(mask)
    if not feet:
        return 0.0
    h, w = mask.shape
    x = float(np.mean([f[0] for f in feet])) + 0.5
    over = mask
    if face_box is not None:  # the columns of their face: their head's top, not a hand raised beside it
        face = mask[:, max(int(face_box[0] * w), 0):min(int(np.ceil((face_box[0] + face_box[2]) * w)), w)]
        if face.any():
            over = face
    rows = np.flatnonzero(over.any(axis=1))
    if rows[0] == 0:  # the frame's top edge cuts them: their height is not seen
        return 0.0
    f = below_horizon(x, max(f[1] for f in feet) + 1.0, (w, h), pitch, focal_px)
    t = below_horizon(x, float(rows[0]), (w, h), pitch, focal_px)
    if f < MIN_BELOW or f <= t:
        return 0.0
    height = PERSON_HEIGHT_M * f / (f - t)
    return float(height) if CAMERA_RANGE[0] <= height <= CAMERA_RANGE[1] else 0.0


class ClipFrames:
    def __init__(self, bundle: ClipBundle):
        self.bundle = bundle
        source = bundle.source  # the bundle's frame, before --max-size at render: what the pans are measured in
        self.bundle_size = output_frame((source["width"], source["height"]), int(bundle.record["options"]["max_size"]))
        self._cameras: dict[int, object] = {}  # frame -> the camera its background is seen through
        self._pitches: dict[int, tuple[float, str, float]] = {}  # shot -> (degrees the map is tilted by, how it
        # was read, metres the camera stood above the ground)
        self.people = [e.index for e in bundle.frames if e.state == "person"]
        self._shot_starts: dict[int, int] = {}  # shot -> its first frame with a person
        for k in self.people:
            self._shot_starts.setdefault(bundle.frames[k].shot, k)

    def grown(self, bundle: ClipBundle) -> ClipFrames:
        """These frames' answers over ``bundle``: the same clip with more of its frames inferred (a relit
        clip that follows its inference, :mod:`viewer.photo.clip_follow`). What was read (the lenses,
        the shots' horizons, the frames with a person) is kept: it came from frames already final; only
        the new frames are looked at (a frame at a time over a 36,000-frame clip)."""
        grown = copy.copy(self)
        grown.bundle, grown.people, grown._shot_starts = bundle, list(self.people), dict(self._shot_starts)
        for entry in bundle.frames[len(self.bundle.frames):]:
            if entry.state == "person":
                grown.people.append(entry.index)
                grown._shot_starts.setdefault(entry.shot, entry.index)
        return grown

    def nearest(self, index: int, state: str | None = None) -> int:
        """The nearest frame to ``index`` (earlier first) that is not lost (``state``: in that state)."""
        frames = self.bundle.frames
        fits = (lambda e: e.state == state) if state else (lambda e: e.state != "lost")
        for j in range(index, -1, -1):
            if fits(frames[j]):
                return j
        for j in range(index + 1, len(frames)):
            if fits(frames[j]):
                return j
        raise InputError(self.bundle.path, "no frame of the clip to show")  # load_clip_bundle refuses such a bundle

    def shown(self, index: int) -> tuple[int, int]:
        """(the frame output frame ``index`` shows, the frame with a person whose scene renders it): the
        same frame when it has the person; a frame without shows the new background as the nearest
        frame with a person sees it."""
        index = self.nearest(index)
        return index, index if self.bundle.frames[index].state == "person" else self.nearest(index, "person")

    def shot_start(self, shot: int) -> int:
        """The shot's first frame with a person (what is held for the shot is read there)."""
        return self._shot_starts[shot]

    def scene(self, index: int, sizes: tuple = (None, None)):
        """Frame ``index``'s scene, its maps at ``--size`` and its frame at most ``--max-size`` (``sizes``)."""
        from viewer.scene.resampling import load_sized_scene

        return load_sized_scene(self.bundle.scene_path(index), *sizes)

    def background_camera(self, index: int):
        """The camera the map behind frame ``index`` is seen through: in a clip inferred as one, its
        shot's first frame with a person's (each frame's own lens follows the person's size in the
        frame, and the map behind would zoom with it); frame by frame, the frame's own."""
        from viewer.scene.camera import Camera

        source = index if not self.bundle.temporal else self.shot_start(self.bundle.frames[index].shot)
        if source not in self._cameras:
            self._cameras[source] = Camera.from_json(read_json(self.bundle.scene_path(source) / "scene.json",
                                                               "scene bundle description")["camera"])
        return self._cameras[source]

    def pitch(self, person: int) -> tuple[float, str]:
        """(degrees the map is tilted by so that its horizon lies where the clip's camera sees its own,
        how that was read) for the shot of frame ``person`` (a person's): read once, on the shot's first
        frame with a person, from the old scene's vertical edges (:func:`viewer.plate.horizon.vertical_horizon`,
        the person's own edges left out), as a plate's horizon is read. A camera looking down sees the
        new ground under the person's feet, not the map's horizon across the middle of the frame. 0 frame
        by frame (each frame relit exactly as a photo, which has no such reading)."""
        pitch, how, _ = self._shot_camera(person)
        return pitch, how

    def camera_height(self, person: int) -> float:
        """Metres above the ground the clip's camera stood in the shot of frame ``person`` (``Look.camera_height``:
        the map's ground seen from there), read on the shot's first frame with a person once its horizon
        was read (:meth:`pitch`): a person of ``PERSON_HEIGHT_M`` standing with their feet ``f`` and the top
        of their head ``t`` below the horizon (the tangents of the angles down, through the camera the map
        is seen through, tilted by the pitch) is seen from ``PERSON_HEIGHT_M f / (f - t)`` metres, as a
        plate's people give its camera's height. 0 (the map as taken) when the horizon was not read, the
        feet are not in the frame, or they stand at the horizon (:data:`MIN_BELOW`)."""
        return self._shot_camera(person)[2]

    def _shot_camera(self, person: int) -> tuple[float, str, float]:
        """(pitch, how it was read, camera height) of the shot of frame ``person``, read once."""
        import cv2
        import numpy as np

        from viewer.files.imageio import linear_to_srgb
        from viewer.plate.horizon import vertical_horizon
        from viewer.plate.loader import DEFAULT_FOCAL_35

        if not self.bundle.temporal:
            return 0.0, "frame by frame: the camera taken as level", 0.0
        shot = self.bundle.frames[person].shot
        if shot not in self._pitches:
            first = self.shot_start(shot)
            frame = self.scene(first).frame
            srgb = (np.clip(linear_to_srgb(frame.photo), 0.0, 1.0) * 255 + 0.5).astype(np.uint8)
            person_px = cv2.dilate((frame.alpha > 0.05).astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
            # the lens the clip was filmed with (its EXIF, else a phone's, as a plate's) finds the horizon's row;
            # the map is seen through the background camera, whose tilt puts its horizon on that row
            lens = focal_pixels(frame.focal_35mm or DEFAULT_FOCAL_35, srgb.shape[1::-1])
            below, how = vertical_horizon(srgb, lens, person_px)
            camera = self.background_camera(first)
            seen_through = camera.focal_at(srgb.shape[1::-1])
            if below is None:
                self._pitches[shot] = (0.0, how, 0.0)
            else:
                pitch = -float(np.degrees(np.arctan(below * lens / seen_through)))
                self._pitches[shot] = (pitch, how, person_seen_from(frame.alpha > 0.5, pitch, seen_through, frame.face_box))
        return self._pitches[shot]

    def camera_turn(self, index: int, person: int) -> tuple[float, float]:
        """(yaw, tilt) in degrees the map turns at frame ``index`` with the clip's camera: the shot's
        pitch (:meth:`pitch`) and the turn since the shot began (:meth:`pan_turn`)."""
        yaw, tilt = self.pan_turn(index, person)
        return yaw, self.pitch(person)[0] + tilt

    def pan_turn(self, index: int, person: int) -> tuple[float, float]:
        """(yaw, tilt) in degrees the camera turned at frame ``index`` since its shot began (the old
        background's motion), seen through the background camera of frame ``person``: the map turns
        by as much, so the new background moves as the old one did."""
        camera = self.background_camera(person)
        focal = camera.focal_at(self.bundle_size)  # at the bundle's frame, as the pan
        return turned(self.bundle.frames[index].pan, focal)
