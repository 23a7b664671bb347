"""The window's layout: the image area beside the side panel (narrower on a small window), and the
key help the panel shows (shared by the app, which places the image, and the panel, which draws
itself)."""

from __future__ import annotations

PANEL_WIDTH = 400  # the side panel's width on a wide window
PANEL_MIN = 300  # and on a small one (900 px wide: 600 px of image)
PANEL_SHARE = 0.34  # of the window's width, between the two
SMALL_HEIGHT = 760  # on a window lower than this only the lighting and the map are expanded (until the user opens others)
KEYS = (
    ("drag on the image", "turn the lighting (left-right: longitude, up-down: tilt)"),
    ("wheel", "exposure; Ctrl+wheel: zoom; right-drag: pan"),
    ("on a plate", "drag the person: move them; wheel: scale them about their feet (--plate, or the panel's Plate)"),
    ("F", "fit the image (reset zoom and pan)"),
    ("0", "reset the lighting rotation"),
    ("S", "save the frame: PNG, HDR EXR and the lights as JSON"),
    ("R", "record what you do; R again renders it at the video's frame rate (a clip: the relit clip, every frame, with its audio)"),
    ("Space, Left / Right", "a clip: play / pause; a frame back / on (the slider scrubs; Home / End: first / last)"),
    ("T", "record a 360 degree turn of the lighting (T again stops)"),
    ("B", "before / after: the original photo left of a split (a photo's scene)"),
    ("G", "the person's shadow on the ground, on or off (on when the feet show)"),
    ("Ctrl+Z / Ctrl+Y", "undo / redo a change of your lights"),
    ("Q / Esc", "quit"),
)


def panel_width(window_width: int) -> int:
    """The side panel's width for a window ``window_width`` pixels wide."""
    return int(min(PANEL_WIDTH, max(PANEL_MIN, round(PANEL_SHARE * window_width))))


MAX_AREA = (1000, 860)  # largest image area the window opens with (pixels)
MIN_AREA = 480


def image_area_size(size: tuple[int, int]) -> tuple[int, int]:
    """The image area for an output of ``size``: its aspect, at most MAX_AREA, at least MIN_AREA
    on the shorter side where that fits."""
    w, h = size
    scale = min(MAX_AREA[0] / w, MAX_AREA[1] / h, max(MIN_AREA / min(w, h), 1.0))
    return max(int(round(w * scale)), MIN_AREA // 2), max(int(round(h * scale)), MIN_AREA // 2)
