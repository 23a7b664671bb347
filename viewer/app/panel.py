"""The side panel (imgui): lighting, per-light size sliders (sigma shown as the light's angular
size in degrees), shading, views, map, recording, frame time, keys. It keeps its own state
(:class:`PanelState`), reads the window's, and changes it through the app's actions or the
session's own methods."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from imgui_bundle import imgui, implot

from viewer.app.interaction import exposed
from viewer.app.layout import KEYS, SMALL_HEIGHT, panel_width
from viewer.app.preview import PREVIEW_LEVELS
from viewer.app.session import BACKGROUND_NAMES, SHADOW_MODES, VIEW_NAMES
from viewer.gl.presets import PRESETS
from viewer.lighting.median_cut import LUMINANCE
from viewer.lighting.placed_lights import MAX_SIZE, RIGS, PlacedLight, free_spot, kelvin_to_rgb
from viewer.scene.area_lights import azimuth_elevation
from viewer.scene.look import VIEWS
from viewer.scene.shadow_space import ANGULAR_SIGMA

# the labels drawn beside sliders and combos (each widget leaves the longest one's room: none is cut)
LABELS = ("longitude", "tilt", "exposure", "map", "yours", "before | after", "quality", "shadows", "view",
          "number of lights", "turn frames", "frame")
LIGHT_COUNT_SLIDER = 64  # the map's lights the slider offers (the final preset's count; a light file holds up to area_lights.MAX_LIGHTS)
SIGMA_SLIDER = 30.0  # the size sliders' top, sigma units (the fits give at most light_size.SIGMA_MAX, 20)
DEG_PER_SIGMA = math.degrees(ANGULAR_SIGMA)  # the slider shows a light's size: its angular sigma in degrees


@dataclass
class PanelState:
    """What the panel keeps between frames, its own: the window's state it only reads, and it
    changes that state through the app's actions (:mod:`viewer.app.actions`)."""

    widgets: dict = field(default_factory=dict)  # name -> [x0, y0, x1, y1] of the widgets drawn this frame
    height: float = 0.0  # its content, drawn or not (the first frame fits the window to it)
    adjusted: float = 0.0  # when a widget was last held (its changes preview until it is let go)
    show_browser: bool = False
    plate_next: bool = False  # the next photo opened is a plate (a background to put the person into), not a person
    rig_choice: int = 0  # the rig the combo shows
    light_count: int | None = None  # the count slider's value while it is held
    ids: dict = field(default_factory=dict)  # imgui's ID of each widget drawn this frame -> its name
    content_right: float = 0.0  # the panel's content's right edge (screen x): no widget or label past it
    id_conflicts: list = field(default_factory=list)  # names of widgets that shared an ID with another (imgui's "conflicting ID")
    clip_shown: tuple = ()  # a clip's (frame slider's value, the words under it) as drawn this frame (the state file's)


def _remember(app, name: str):
    """Where the widget just drawn is (the state file's ``widgets``), and whether its imgui ID is
    another widget's this frame: two widgets with one ID take each other's clicks (the map chooser
    never opened beside the "map" intensity slider, issue 45); the state file lists them."""
    lo, hi = imgui.get_item_rect_min(), imgui.get_item_rect_max()
    app.panel.widgets[name] = [lo.x, lo.y, hi.x, hi.y]
    item = imgui.get_item_id()
    if not item or not imgui.is_item_visible():  # text and images take no clicks; a widget scrolled out of its box has no ID of its own
        return
    other = app.panel.ids.setdefault(item, name)
    if other != name:
        pair = " / ".join(sorted((other, name)))
        if pair not in app.panel.id_conflicts:
            app.panel.id_conflicts.append(pair)


def _swatch(intensity: np.ndarray, peak: float) -> imgui.ImVec4:
    c = np.clip(intensity / max(peak, 1e-30), 0, 1) ** (1 / 2.2)
    return imgui.ImVec4(float(c[0]), float(c[1]), float(c[2]), 1.0)


def draw_panel(app):
    w, h = app.window.size
    app.panel.widgets = {}  # the widgets drawn this frame (a collapsed section's are not there)
    app.panel.ids = {}
    width = panel_width(w)
    imgui.set_next_window_pos(imgui.ImVec2(w - width, 0))
    imgui.set_next_window_size(imgui.ImVec2(width, h))
    # the scroll bar's place always kept: widths that do not depend on whether the panel scrolls (a
    # scroll bar coming and going would change the thumbnail's height, and so whether it scrolls)
    flags = (imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
             | imgui.WindowFlags_.always_vertical_scrollbar)
    imgui.begin("relight", None, flags)
    # every widget leaves its label's room at the right: the longest label fits whatever the width
    # ("before | after" was cut at 973 pixels)
    app.panel.content_right = imgui.get_cursor_screen_pos().x + imgui.get_content_region_avail().x
    imgui.push_item_width(-(max(imgui.calc_text_size(label).x for label in LABELS) + imgui.get_style().item_inner_spacing.x))
    _status(app)
    _clip(app)
    _lighting(app)
    _map(app)
    _plate(app)
    _placed(app)
    _shading(app)
    _lights(app)
    _record(app)
    _frame_time(app)
    if imgui.collapsing_header("Keys and mouse"):
        _keys()
    imgui.pop_item_width()
    app.panel.height = imgui.get_cursor_pos_y() + imgui.get_style().window_padding.y  # all of it, scrolled or not
    # a slider held (or a click): the preview until it is let go (app._render); a text box being typed in
    # (the browser's path) holds nothing of the lighting: the picture stays the full-quality one
    if imgui.is_any_item_active() and not imgui.get_io().want_text_input:
        app.panel.adjusted = time.perf_counter()
    imgui.end()


def draw_progress(app):
    """Every wait the user would otherwise watch without knowing (a photo or a map opening, lights
    fitted, a recording rendered): a bar with its stage and the time left over the image's top
    edge, in view at every window size (the panel's own bars can be scrolled away or below the
    window's edge)."""
    from viewer.app.recording import InteractionRecording

    rec = app.recording
    job = app.scene_job or app.job
    rendering = rec is not None and not (isinstance(rec, InteractionRecording) and rec.capturing) and rec.total
    if job is None and not rendering and app.held is None:  # (a clip's next frame being drawn is no new light)
        return
    x, y, w, _ = app.image_rect()
    area_x, area_y, area_w, _ = app.image_area()
    left, top = max(x, area_x) + 8, max(y, area_y) + 8
    width = max(min(x + w, area_x + area_w) - left - 8, 120)
    imgui.set_next_window_pos(imgui.ImVec2(left, top))
    imgui.set_next_window_size(imgui.ImVec2(min(width, 460), 0))
    imgui.set_next_window_bg_alpha(0.8)
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_saved_settings
             | imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.always_auto_resize | imgui.WindowFlags_.no_inputs)
    imgui.begin("progress", None, flags)
    # the stage and the time left as wrapped text above each bar: a bar's own text is centred and
    # clipped at both ends ("it the photo's lights done (8 of 11), about 2 s left")
    if job is not None:
        imgui.text_wrapped(app.message or "working")
        imgui.text_wrapped(job.stage)
        imgui.progress_bar(job.fraction, imgui.ImVec2(-1, 0), f"{100 * job.fraction:.0f} %")
    elif app.held is not None:  # a job's result being drawn (its shadows, over frames): the panel changes with it
        imgui.text_wrapped("drawing the new light")
        imgui.progress_bar(-imgui.get_time(), imgui.ImVec2(-1, 0), "")
    if rendering:
        words = rec.time_left.words()
        imgui.text_wrapped(f"rendering {rec.done} / {rec.total} frames" + (f", {words}" if words else "")
                           + f"; {'T' if rec.kind == 'turntable' else 'R'} stops")
        imgui.progress_bar(rec.fraction, imgui.ImVec2(-1, 0), f"{100 * rec.fraction:.0f} %")
    _remember(app, "progress")
    imgui.end()


def _keys():
    """The keys and the mouse, a row each, the words wrapped to the panel's width."""
    if imgui.begin_table("keys", 2, imgui.TableFlags_.sizing_fixed_fit):
        imgui.table_setup_column("key", imgui.TableColumnFlags_.width_fixed)
        imgui.table_setup_column("does", imgui.TableColumnFlags_.width_stretch)
        for key, does in KEYS:
            imgui.table_next_row()
            imgui.table_next_column()
            imgui.text_unformatted(key)
            imgui.table_next_column()
            imgui.text_wrapped(does)
        imgui.end_table()


def _open(app, first: bool) -> int:
    """The flag for a section's header: expanded on a tall window, or when ``first`` (the section a
    small window shows); a section the user opened or closed stays as they left it."""
    return imgui.TreeNodeFlags_.default_open if first or app.window.size[1] >= SMALL_HEIGHT else 0


def _status(app):
    """Messages and the fitting's progress in a box of fixed height, so a message never moves the
    widgets below it (a click meant for one would land on another)."""
    height = 2 * imgui.get_text_line_height_with_spacing() + imgui.get_frame_height_with_spacing()
    imgui.begin_child("status", imgui.ImVec2(0, height), 0, imgui.WindowFlags_.no_scrollbar)
    if app.error:
        imgui.push_text_wrap_pos(0.0)
        imgui.text_colored(imgui.ImVec4(1, 0.4, 0.3, 1), app.error)
        imgui.pop_text_wrap_pos()
    elif app.message:
        imgui.text_wrapped(app.message)
    job = app.scene_job or app.job  # one bar: the person being opened first, else the map being fitted
    if job is not None:  # the file's name is in the message above; the bar names the stage (a long label is cut)
        imgui.progress_bar(job.fraction, imgui.ImVec2(-1, 0), job.stage)
    elif app.captures or app.videos:  # where S and R write (--out-dir), one click to paste it elsewhere
        if imgui.small_button("copy the folder's path"):
            imgui.set_clipboard_text(str(app.config.out_dir.resolve()))
        _remember(app, "copy folder")
    imgui.end_child()


def _clip(app):
    """A clip's timeline: play and pause, the frame slider (scrubs), where the frame is in the clip."""
    t = app.timeline
    if t is None or not imgui.collapsing_header("Clip", imgui.TreeNodeFlags_.default_open):
        return
    imgui.begin_disabled(app.recording is not None)  # a recording sets the frames
    try:
        if imgui.button("Pause (space)" if t.playing else "Play (space)"):
            t.play()
        _remember(app, "clip play")
        imgui.same_line()
        _, t.every_frame = imgui.checkbox("every frame", t.every_frame)
        _remember(app, "clip every frame")
        # the frame on screen, as the words below say (the one asked for may still be coming)
        changed, frame = imgui.slider_int("frame", t.on_screen + 1, 1, t.count)
        _remember(app, "clip frame")
        if changed:
            t.seek(frame - 1)
    finally:
        imgui.end_disabled()
    words = t.describe()
    imgui.text_wrapped(words)
    app.panel.clip_shown = (t.on_screen + 1, words)
    # the rate and the frames relit ahead on a line of their own, there whether playing or not: the widgets below never move
    slow = t.playing and t.rate is not None and t.rate < 0.9 * t.fps
    line = ("" if not slow else f"{t.rate:.1f} frames a second, slower than its {t.fps:.0f}" if t.every_frame
            else f"showing {t.rate:.1f} of its {t.fps:.0f} frames a second")
    relit = app.relit.count if app.relit is not None and app.plate is None else t.count
    if relit < t.count:
        line += ("; " if line else "") + f"{relit} of {t.count} relit ahead"
    imgui.text_disabled(line)


def _lighting(app):
    if not imgui.collapsing_header("Lighting", imgui.TreeNodeFlags_.default_open):
        return
    held = app.held  # a new map or person coming in: the picture's lighting, not to be changed meanwhile
    imgui.begin_disabled(held is not None)
    try:
        _lighting_controls(app, held)
    finally:
        imgui.end_disabled()


def _lighting_controls(app, held):
    s = app.session
    v = held.look if held is not None else s.look
    changed, yaw = imgui.slider_float("longitude", v.yaw, -180.0, 180.0, "%.1f deg")
    _remember(app, "longitude")
    if changed:
        s.update(yaw=yaw)
    changed, tilt = imgui.slider_float("tilt", v.tilt, -90.0, 90.0, "%.1f deg")
    _remember(app, "tilt")
    if changed:
        s.update(tilt=tilt)
    # the slider leaves room for "level" (the photo's brightness under the lights now) and its label
    level = imgui.calc_text_size("level").x + 2 * imgui.get_style().frame_padding.x + imgui.get_style().item_spacing.x
    imgui.set_next_item_width(imgui.calc_item_width() - level)
    changed, exposure = imgui.slider_float("##exposure", v.exposure_stops, -10.0, 10.0, "%+.2f stops")
    _remember(app, "exposure")
    if changed:
        s.look = exposed(s.look, exposure)
    imgui.same_line()
    if imgui.button("level"):
        app.actions.level_exposure()
    if imgui.is_item_hovered():
        imgui.set_tooltip("expose for the photo's brightness under the lights now\n(a new map keeps the exposure you had)")
    _remember(app, "level exposure")
    imgui.same_line(0, imgui.get_style().item_inner_spacing.x)
    imgui.text("exposure")
    changed, intensity = imgui.slider_float("map##intensity", v.intensity, 0.0, 8.0, "map's lights x %.2f",
                                            imgui.SliderFlags_.logarithmic)
    _remember(app, "intensity")
    if changed:
        s.update(intensity=intensity)
    if s.scene.frame is not None:  # before / after: the original photo left of the split (B toggles)
        changed, compare = imgui.slider_float("before | after", v.compare, 0.0, 1.0,
                                              "photo %.2f" if v.compare > 0.0 else "off")
        _remember(app, "compare")
        if changed:
            s.update(compare=compare)
    changed, ground = imgui.checkbox("ground shadow (G)", held.ground if held is not None else s.ground_shown)
    _remember(app, "ground")
    if imgui.is_item_hovered():
        imgui.set_tooltip("the person's shadow on the ground at the feet, over the background\n"
                          "(on by default when the feet are in the frame and the map is behind)")
    if changed:
        s.update(ground=ground)
    imgui.same_line()  # what the ground's shadow falls on, on its row
    names = list(BACKGROUND_NAMES)
    shown = list(BACKGROUND_NAMES.values())
    background = held.look.background if held is not None else s.look.background
    imgui.set_next_item_width(imgui.get_content_region_avail().x - imgui.calc_text_size("behind").x
                              - imgui.get_style().item_inner_spacing.x)
    changed, i = imgui.combo("behind", shown.index(background) if background in shown else 0, names)
    _remember(app, "behind")
    if imgui.is_item_hovered():
        imgui.set_tooltip("behind the person: the map, the photo's own background (shown as it is, whatever the\n"
                          "exposure), or a grey")
    if changed:
        s.update(background=BACKGROUND_NAMES[names[i]])


def _shading(app):
    s = app.session
    if not imgui.collapsing_header("Shading", _open(app, False)):
        return
    lk = s.look
    presets = list(PRESETS)
    changed, i = imgui.combo("quality", presets.index(app.preset) if app.preset in presets else 0, presets)
    _remember(app, "quality")
    if imgui.is_item_hovered() and app.preset in PRESETS:
        p = PRESETS[app.preset]
        imgui.set_tooltip(f"{p.summary}\nchosen as {p.rule} (docs/results.md)")
    if changed:
        app.actions.set_preset(presets[i])
    names = list(SHADOW_MODES)
    current = list(SHADOW_MODES.values()).index(lk.shadows)
    changed, i = imgui.combo("shadows", current, names)
    _remember(app, "shadows")
    if changed:
        s.update(shadows=SHADOW_MODES[names[i]])
    if s.refine_error:  # the network failed: the mode went back to soft, and this says why
        imgui.text_colored(imgui.ImVec4(1.0, 0.45, 0.4, 1.0), s.refine_error)
    elif lk.shadows == "refined":  # one line, there all the time under "refined": nothing below it moves
        imgui.text_disabled("refining (soft shown meanwhile)..." if s.refining else "refined shadows shown")
    changed, diffuse = imgui.checkbox("diffuse", lk.diffuse)
    if changed:
        s.update(diffuse=diffuse)
    imgui.same_line()
    changed, specular = imgui.checkbox("specular", lk.specular)
    if changed:
        s.update(specular=specular)
    imgui.same_line()
    changed, skin = imgui.checkbox("skin", lk.skin)  # light scattered under the skin (a photo's)
    if imgui.is_item_hovered():
        imgui.set_tooltip("light scattered under the skin: soft, warm terminators on a photo's skin")
    if changed:
        s.update(skin=skin)
    labels = [VIEW_NAMES[v] for v in VIEWS]
    changed, i = imgui.combo("view", VIEWS.index(lk.view), labels)
    _remember(app, "view")
    if changed:
        s.update(view=VIEWS[i])


def _lights(app):
    held = app.held  # a new map or person coming in: the picture's lights, not to be changed meanwhile
    n = len(held.sigma if held is not None else app.session.sigma)
    if not imgui.collapsing_header(f"Area lights ({n})", _open(app, False)):
        return
    imgui.begin_disabled(held is not None)
    try:
        _light_rows(app, held, n)
    finally:
        imgui.end_disabled()


def _light_rows(app, held, n: int):
    s = app.session
    sigma, look = (held.sigma, held.look) if held is not None else (s.sigma, s.look)
    imgui.set_next_item_width(140)
    shown = app.panel.light_count if app.panel.light_count is not None else app.n_lights
    changed, count = imgui.slider_int("number of lights", shown, 1, LIGHT_COUNT_SLIDER)
    _remember(app, "number of lights")
    if changed:
        app.panel.light_count = count
    if imgui.is_item_deactivated_after_edit():
        count, app.panel.light_count = app.panel.light_count, None
        if count is not None and count != n and app.env_path is not None:
            app.actions.refit(count)
    if app.env_path is None:
        imgui.text_disabled("(no map to refit: lights came from a file)")
    lights = held.lights if held is not None else s.rotated_lights()
    lum = lights.intensity @ LUMINANCE
    peak = float(lights.intensity.max()) if n else 1.0
    total = float(lum.sum()) or 1.0
    imgui.text_disabled("       #  azim  elev   size (angular sigma)")
    imgui.begin_child("lights", imgui.ImVec2(0, 165), imgui.ChildFlags_.borders)
    for i in np.argsort(-lum, kind="stable"):
        i = int(i)
        imgui.push_id(str(i))
        az, el = azimuth_elevation(lights.direction[i])
        imgui.color_button("##c", _swatch(lights.intensity[i], peak), 0, imgui.ImVec2(18, 18))
        if imgui.is_item_hovered():  # short lines: the panel is at the window's right edge
            r, g, b = (f"{c:.3g}" for c in lights.intensity[i])
            imgui.set_tooltip(f"light {i}: {100 * lum[i] / total:.1f} % of the light\n"
                              f"azimuth {az:+.0f}, elevation {el:+.0f} deg\n"
                              f"size {sigma[i] * DEG_PER_SIGMA:.1f} deg (sigma {sigma[i]:.2f})\n"
                              f"intensity (RGB) {r} / {g} / {b}")
        imgui.same_line()
        selected = look.view == "shadow" and look.light == i
        if imgui.selectable(f"{i:2d} {az:+4.0f} {el:+3.0f}", selected, 0, imgui.ImVec2(92, 0))[0]:
            s.update(view="shadow", light=i) if not selected else s.update(view="final")
        imgui.same_line()
        imgui.set_next_item_width(-1)
        changed, size = imgui.slider_float("##sigma", float(sigma[i]) * DEG_PER_SIGMA, 0.0, SIGMA_SLIDER * DEG_PER_SIGMA,
                                           "%.1f deg")
        _remember(app, f"sigma {i}")
        if changed:
            s.set_sigma(i, size / DEG_PER_SIGMA)
        imgui.pop_id()
    imgui.end_child()
    imgui.push_text_wrap_pos(0.0)
    imgui.text_disabled("click a light to see its shadow; sorted by brightness")
    imgui.pop_text_wrap_pos()
    _remember(app, "lights hint")


def _placed(app):
    """The user's own lights: a rig, add, edit (direction, size, intensity, colour temperature),
    delete, undo and redo, save the rig."""
    s = app.session
    if not imgui.collapsing_header(f"Your lights ({len(s.placed)})", _open(app, False)):
        return
    level = app.actions.placed_level()
    # always drawn (greyed out without lights of yours), here with them: a rig that adds the first
    # light moves nothing (the map's thumbnail and "open a file" took clicks meant for each other)
    imgui.begin_disabled(not s.placed)
    changed, placed_level = imgui.slider_float("yours", s.look.placed_intensity, 0.0, 8.0,
                                               "all x %.2f" if s.placed else "none yet", imgui.SliderFlags_.logarithmic)
    imgui.end_disabled()
    _remember(app, "placed intensity")
    if changed and s.placed:
        s.update(placed_intensity=placed_level)
    names = list(RIGS)
    imgui.set_next_item_width(140)
    _, app.panel.rig_choice = imgui.combo("##rig", app.panel.rig_choice, names)
    imgui.same_line()
    if imgui.button("use rig"):
        app.actions.use_rig(names[app.panel.rig_choice])
    _remember(app, "use rig")
    imgui.same_line()
    if imgui.button("add light"):
        azimuth, elevation = free_spot(s.placed)  # not on top of a light already there
        s.set_placed(s.placed + (PlacedLight(azimuth, elevation, intensity=level),))
    _remember(app, "add light")
    _, s.keep_absolute = imgui.checkbox("keep absolute intensities", s.keep_absolute)
    _remember(app, "keep absolute")
    if imgui.is_item_hovered():
        imgui.set_tooltip("on: your lights keep their intensities when the map changes\n"
                          "off: they keep their share of the light (scaled with the map's brightness)")
    if imgui.button("undo"):  # short labels: the row fits the narrowest panel (the keys in the tooltips)
        s.undo()
    if imgui.is_item_hovered():
        imgui.set_tooltip("Ctrl+Z")
    _remember(app, "undo")
    imgui.same_line()
    if imgui.button("redo"):
        s.redo()
    if imgui.is_item_hovered():
        imgui.set_tooltip("Ctrl+Y")
    _remember(app, "redo")
    imgui.same_line()
    if imgui.button("save rig") and s.placed:
        app.actions.save_rig()
    _remember(app, "save rig")
    placed = list(s.placed)
    # in a box of its own height (a light in view, the rest scroll): lights added or deleted move
    # nothing below it (a click meant for one widget would land on another)
    one = 3 * imgui.get_frame_height_with_spacing() + imgui.get_style().item_spacing.y
    imgui.begin_child("placed lights", imgui.ImVec2(0, one), imgui.ChildFlags_.borders)
    if not placed:
        imgui.text_disabled("none yet: use a rig, add a light,\nor click the map's thumbnail")
    for j, p in enumerate(placed):
        imgui.push_id(f"placed{j}")
        imgui.separator()
        imgui.color_button("##c", _swatch(kelvin_to_rgb(p.kelvin), 2.0), 0, imgui.ImVec2(18, 18))
        imgui.same_line()
        imgui.text(f"yours {j + 1} (light {len(s.base_lights) + j})")
        imgui.same_line()
        if imgui.small_button("aim"):
            app.actions.start_aiming(j)
        _remember(app, f"placed {j} aim")
        imgui.same_line()
        if imgui.small_button("delete"):
            s.set_placed(placed[:j] + placed[j + 1:])
            imgui.pop_id()
            break
        edits = {}
        half = (imgui.get_content_region_avail().x - imgui.get_style().item_spacing.x) / 2
        for k, (name, low, high, fmt, flags) in enumerate((
                ("azimuth", -180.0, 180.0, "azimuth %+.0f deg", 0), ("elevation", -90.0, 90.0, "elevation %+.0f deg", 0),
                ("size", 0.0, MAX_SIZE, "size %.1f deg", 0),
                ("intensity", 0.0, 8.0 * level, "intensity %.3g", imgui.SliderFlags_.logarithmic),
                ("kelvin", 1500.0, 12000.0, "%.0f K", 0))):
            if k % 2:
                imgui.same_line()  # two sliders a row: the panel stays short with several lights
            imgui.set_next_item_width(half)
            changed, value = imgui.slider_float(f"##{name}", getattr(p, name), low, high, fmt, flags)
            _remember(app, f"placed {j} {name}")
            if imgui.is_item_activated():  # one undo step per drag of a slider
                s.history.record(s.placed)
            if changed:
                edits[name] = value
        if edits:
            placed[j] = replace(p, **edits)
            s.set_placed(placed, record=False)
        imgui.pop_id()

    imgui.end_child()

def _map(app):
    if not imgui.collapsing_header("Environment map", _open(app, True)):
        return
    maps = list(app.config.bundled_maps)
    names = [p.stem for p in maps]
    shown = app.shown[0]  # the picture's map: a new one shows here the frame it shows there
    current = maps.index(shown) if shown in maps else -1
    label = shown.name if shown else "(none)"
    if imgui.begin_combo("map", label):
        for i, name in enumerate(names):
            if imgui.selectable(name, i == current)[0] and i != current:
                app.actions.open_map(maps[i])
        imgui.end_combo()
    _remember(app, "map")
    _thumbnail(app)
    changed, app.panel.show_browser = imgui.checkbox("open a file...", app.panel.show_browser)
    _remember(app, "open a file")
    if changed and app.panel.show_browser:
        app.workers["lights"].start()  # a map chosen next finds its fitter started (torch loaded) while the user looks
    if imgui.is_item_hovered():
        imgui.set_tooltip("a photo, a scene bundle, an environment map or a rig (or drop one on the window)")
    if app.panel.show_browser:
        _, app.panel.plate_next = imgui.checkbox("the next photo opened is the plate", app.panel.plate_next)
        _remember(app, "plate next")
        if imgui.is_item_hovered():
            imgui.set_tooltip("a background photo (chosen below, or dropped on the window) to put the person into:\n"
                              "they stand on its ground, lit by its light, their shadow on it")
        chosen = app.browser.draw(lambda name: _remember(app, f"browser {name}"))
        if chosen is not None:
            app.actions.open_file(chosen)


def _plate(app):
    """The plate the person is put into (issue 47), when there is one: where they stand, the camera's
    warning, its light, and its removal (a plate is opened by --plate, or by the browser's "the next
    photo opened is the plate")."""
    plate = app.plate
    if plate is None:
        return
    if not imgui.collapsing_header(f"Plate: {Path(plate.plate.source).name}", imgui.TreeNodeFlags_.default_open):
        return
    p = plate.place
    imgui.text(f"{plate.plate.size[0]}x{plate.plate.size[1]}, lit by " + ("its own light" if plate.light == "plate" else plate.light))
    if plate.notes:
        imgui.push_text_wrap_pos(0.0)
        imgui.text_disabled("; ".join(plate.notes))
        imgui.pop_text_wrap_pos()
    clip = plate.anchor is not None  # a clip's: placed by its first frame with the person, the others moving with them
    imgui.text(f"feet at {p.x:.2f},{p.y:.2f}; {p.height:.2f} of it tall" + (" (in the clip's first frame with them)" if clip else ""))
    if imgui.is_item_hovered():
        imgui.set_tooltip("drag the person to move them; the wheel on them scales them about their feet\n"
                          + ("a clip's person is placed by their first frame; they walk across the plate as across their frame\n"
                             "relight render CLIP --plate PLATE --at X,Y --height H gives the same" if clip else
                             "relight render BUNDLE --plate PLATE --at X,Y --height H gives the same"))
    for line in (*plate.mismatches(app.session.scene), plate.error):
        if line:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_colored(imgui.ImVec4(1.0, 0.75, 0.3, 1.0), line)
            imgui.pop_text_wrap_pos()
    if plate.light != "plate":
        if imgui.button("light from the plate"):
            app.actions.open_map(plate.light_map)
        _remember(app, "light from the plate")
        if imgui.is_item_hovered():
            imgui.set_tooltip("the person lit by the plate's own light (a map made from it) in place of the map's")
        imgui.same_line()
    if imgui.button("remove the plate"):
        app.actions.remove_plate()
    _remember(app, "remove the plate")


def _thumbnail(app):
    """The map as its light arrives now, a dot on each light (hollow: the map's; filled and
    numbered: yours). A click aims the light being aimed there, or adds a light there."""
    s = app.session
    _, environment, map_lights = app.shown  # the picture's map and lights (a new map: once its frame shows)
    if environment is None:
        return
    yaw, tilt = s.rendered_look.yaw, s.rendered_look.tilt  # (a clip frame's camera turn too: as the engines)
    thumb = app.thumbnail
    tex = thumb.update(environment)
    width = imgui.get_content_region_avail().x
    size = imgui.ImVec2(width, width / 2)
    uv0, uv1 = thumb.uv_range(yaw)
    imgui.image(imgui.ImTextureRef(tex.glo), size, imgui.ImVec2(*uv0), imgui.ImVec2(*uv1))
    _remember(app, "thumbnail")
    lo = imgui.get_item_rect_min()
    if imgui.is_item_clicked(0):
        mouse = imgui.get_io().mouse_pos
        app.actions.aim_direction(thumb.direction_at((mouse.x - lo.x) / size.x, (mouse.y - lo.y) / size.y, yaw, tilt))
    if imgui.is_item_hovered():
        imgui.set_tooltip("the map as it lights the person now\nmiddle: behind the person; edges: the camera's side\n"
                          "click: aim the light being aimed here, or add one here")
    draw = imgui.get_window_draw_list()
    ring = imgui.get_color_u32(imgui.ImVec4(1.0, 1.0, 1.0, 0.9))
    for u, v in thumb.points(map_lights.rotated(yaw, tilt).direction, yaw, tilt):
        draw.add_circle(imgui.ImVec2(lo.x + u * size.x, lo.y + v * size.y), 4.0, ring)
    first = len(s.base_lights)
    for j, ((u, v), p) in enumerate(zip(thumb.points([p.direction for p in s.placed], yaw, tilt), s.placed)):
        c = _swatch(kelvin_to_rgb(p.kelvin), 2.0)
        centre = imgui.ImVec2(lo.x + u * size.x, lo.y + v * size.y)
        draw.add_circle_filled(centre, 5.0, imgui.get_color_u32(c))
        draw.add_circle(centre, 5.0, imgui.get_color_u32(imgui.ImVec4(0.0, 0.0, 0.0, 1.0)))
        draw.add_text(imgui.ImVec2(centre.x + 6.0, centre.y - 7.0), ring, str(first + j))


def _record(app):
    from viewer.app.recording import InteractionRecording

    if not imgui.collapsing_header("Record", _open(app, False)):
        return
    rec = app.recording
    if rec is None:
        if imgui.button("Record clip (R)" if app.timeline is not None else "Record (R)"):
            app.actions.toggle_recording("live")
        _remember(app, "record")
        imgui.same_line()
        if imgui.button("360 turn (T)"):
            app.actions.toggle_recording("turntable")
        _remember(app, "record turn")
        imgui.same_line()
        if imgui.button("Save frame (S)"):
            app.actions.save_frame()
        imgui.set_next_item_width(120)
        changed, frames = imgui.slider_int("turn frames", app.actions.turn_frames, 12, 720)
        if changed:
            app.actions.set_turn_frames(frames)
    elif isinstance(rec, InteractionRecording) and rec.capturing:
        imgui.text(f"recording what you do: {rec.seconds:.1f} s")
        if imgui.button("Stop and render (R)"):
            app.actions.toggle_recording(rec.kind)
        _remember(app, "record")
    else:
        left = rec.time_left.words()
        imgui.progress_bar(rec.fraction, imgui.ImVec2(-1, 0), f"{rec.done} / {rec.total} frames" + (f", {left}" if left else ""))
        if imgui.button("Stop"):
            app.actions.toggle_recording(rec.kind)
        _remember(app, "record")
    imgui.text_disabled(f"to {app.config.out_dir}/")


def _frame_time(app):
    if not imgui.collapsing_header("Frame time"):
        return
    frames = list(app.log.frames)[-240:]
    if not frames:
        return
    ms = np.array([f[0] for f in frames], np.float64)
    kinds = [f[1] for f in frames]
    last = frames[-1]
    working = [m for m, k in frames if k != "idle"]
    med = float(np.median(working)) if working else float(np.median(ms))
    imgui.text(f"last {last[0]:.0f} ms ({last[1]}), median of updates {med:.0f} ms")
    if "drag" in kinds:
        imgui.push_text_wrap_pos(0.0)
        level = PREVIEW_LEVELS[app.pace.level]  # chosen from the dragged frames' times (viewer/app/preview.py)
        imgui.text_disabled(f"while dragging: {level.work} px, a {level.frame} px frame, hard shadows; "
                            "full quality when the mouse stops")
        imgui.pop_text_wrap_pos()
    if implot.begin_plot("##frame time", imgui.ImVec2(-1, 120), implot.Flags_.no_legend | implot.Flags_.no_menus):
        implot.setup_axes("", "ms", implot.AxisFlags_.no_tick_labels, 0)
        implot.setup_axis_limits(implot.ImAxis_.x1, 0, 240, implot.Cond_.always)
        implot.setup_axis_limits(implot.ImAxis_.y1, 0, max(150.0, float(ms.max()) * 1.1), implot.Cond_.always)
        implot.plot_line("frame", np.ascontiguousarray(ms))
        implot.plot_inf_lines("100 ms", np.array([100.0]), implot.Spec(flags=implot.InfLinesFlags_.horizontal))
        implot.end_plot()
