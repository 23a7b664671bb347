"""What the mouse and wheel do, as plain functions (no window, no GL): testable. The lighting's
rotation and the exposure belong to the look (:class:`viewer.scene.look.Look`); where the image sits
in the window (zoom, pan) to :class:`ViewState`.

Dragging on the image turns the lighting as if grabbing the environment map: the map behind the
person follows the cursor (horizontal drag = longitude, vertical drag = tilt, clamped to +-90
degrees). The wheel changes the exposure; with Ctrl it zooms about the cursor.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from viewer.scene.look import EXPOSURE_LIMIT, Look

DEGREES_PER_PIXEL = 0.5  # of mouse motion, in window pixels
EXPOSURE_PER_NOTCH = 0.25  # stops per wheel notch
ZOOM_PER_NOTCH = 1.15
ZOOM_RANGE = (0.25, 8.0)  # at 8x a fitted 1000-pixel image spans 8000 pixels: within GL viewport limits
TILT_RANGE = (-90.0, 90.0)


@dataclass(frozen=True)
class ViewState:
    zoom: float = 1.0  # 1 = the image fitted into the image area
    pan: tuple[float, float] = (0.0, 0.0)  # image-area pixels the image centre is moved by


def dragged(look: Look, dx: float, dy: float) -> Look:
    """Turn the lighting by a mouse motion of (dx, dy) window pixels (y down). Positive yaw turns a
    point in front of the camera to the left, so a drag to the right decreases it."""
    yaw = (look.yaw - dx * DEGREES_PER_PIXEL + 180.0) % 360.0 - 180.0
    tilt = min(max(look.tilt - dy * DEGREES_PER_PIXEL, TILT_RANGE[0]), TILT_RANGE[1])
    return replace(look, yaw=yaw, tilt=tilt)


def exposed(look: Look, stops: float) -> Look:
    """The look at ``stops`` of exposure, held within the look's limits."""
    return replace(look, exposure=min(max(float(stops), -EXPOSURE_LIMIT), EXPOSURE_LIMIT))


def wheeled(look: Look, notches: float) -> Look:
    """Exposure up / down by the wheel."""
    return exposed(look, look.exposure_stops + notches * EXPOSURE_PER_NOTCH)


def zoomed(state: ViewState, notches: float, cursor=(0.0, 0.0), area=(1, 1)) -> ViewState:
    """Zoom about ``cursor`` (area pixels, origin top left)."""
    z = min(max(state.zoom * ZOOM_PER_NOTCH ** notches, ZOOM_RANGE[0]), ZOOM_RANGE[1])
    k = z / state.zoom
    # keep the image point under the cursor fixed: c + pan' - cursor = k (c + pan - cursor)
    cx, cy = area[0] / 2.0, area[1] / 2.0
    px, py = state.pan
    pan = ((cursor[0] - cx) + k * (cx + px - cursor[0]), (cursor[1] - cy) + k * (cy + py - cursor[1]))
    return replace(state, zoom=z, pan=pan)


def panned(state: ViewState, dx: float, dy: float) -> ViewState:
    return replace(state, pan=(state.pan[0] + dx, state.pan[1] + dy))


def image_rect(image_size, area_size, zoom: float = 1.0, pan=(0.0, 0.0)) -> tuple[float, float, float, float]:
    """(x, y, width, height) of the image in the image area (origin top left): fitted into the
    area with its aspect kept, then zoomed and panned."""
    iw, ih = image_size
    aw, ah = area_size
    fit = min(aw / iw, ah / ih) if iw and ih else 1.0
    s = fit * zoom
    w, h = iw * s, ih * s
    return (aw - w) / 2.0 + pan[0], (ah - h) / 2.0 + pan[1], w, h


def image_pixel(point, rect, size) -> tuple[int, int] | None:
    """The (column, row) of an image of ``size`` (width, height) pixels under a window ``point``,
    the image drawn at ``rect`` (x, y, width, height); None outside it."""
    x, y, w, h = rect
    u, v = (point[0] - x) / w, (point[1] - y) / h
    if not (0.0 <= u < 1.0 and 0.0 <= v < 1.0):
        return None
    return min(int(u * size[0]), size[0] - 1), min(int(v * size[1]), size[1] - 1)
