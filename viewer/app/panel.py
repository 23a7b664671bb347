"""The side panel (imgui): lighting, per-light size sliders (sigma shown as the light's angular
size in degrees), shading, views, map, recording, frame time, keys. It keeps its own state
(:class:`PanelState`), reads the window's, and changes it through the app's actions or the
session's own methods."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from imgui_bundle import imgui, implot

from viewer.app.layout import KEYS, panel_width
from viewer.app.panel_lights import lighting_section, lights_section, placed_section, swatch
from viewer.app.panel_state import remember, section_open
from viewer.app.preview import PREVIEW_LEVELS
from viewer.app.session import SHADOW_MODES, VIEW_NAMES
from viewer.gl.presets import PRESETS
from viewer.lighting.placed_lights import kelvin_to_rgb
from viewer.scene.look import VIEWS

# the labels drawn beside sliders and combos (each widget leaves the longest one's room: none is cut)
LABELS = ("longitude", "tilt", "exposure", "map", "yours", "before | after", "quality", "shadows", "view",
          "number of lights", "turn frames", "frame")


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
    lighting_section(app)
    _map(app)
    _plate(app)
    placed_section(app)
    _shading(app)
    lights_section(app)
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
    remember(app, "progress")
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
        remember(app, "copy folder")
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
        remember(app, "clip play")
        imgui.same_line()
        _, t.every_frame = imgui.checkbox("every frame", t.every_frame)
        remember(app, "clip every frame")
        # the frame on screen, as the words below say (the one asked for may still be coming)
        changed, frame = imgui.slider_int("frame", t.on_screen + 1, 1, t.count)
        remember(app, "clip frame")
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


def _shading(app):
    s = app.session
    if not imgui.collapsing_header("Shading", section_open(app, False)):
        return
    lk = s.look
    presets = list(PRESETS)
    changed, i = imgui.combo("quality", presets.index(app.preset) if app.preset in presets else 0, presets)
    remember(app, "quality")
    if imgui.is_item_hovered() and app.preset in PRESETS:
        p = PRESETS[app.preset]
        imgui.set_tooltip(f"{p.summary}\nchosen as {p.rule} (docs/results/results.md)")
    if changed:
        app.actions.set_preset(presets[i])
    names = list(SHADOW_MODES)
    current = list(SHADOW_MODES.values()).index(lk.shadows)
    changed, i = imgui.combo("shadows", current, names)
    remember(app, "shadows")
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
    remember(app, "view")
    if changed:
        s.update(view=VIEWS[i])


def _map(app):
    if not imgui.collapsing_header("Environment map", section_open(app, True)):
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
    remember(app, "map")
    _thumbnail(app)
    changed, app.panel.show_browser = imgui.checkbox("open a file...", app.panel.show_browser)
    remember(app, "open a file")
    if changed and app.panel.show_browser:
        app.workers["lights"].start()  # a map chosen next finds its fitter started (torch loaded) while the user looks
    if imgui.is_item_hovered():
        imgui.set_tooltip("a photo, a scene bundle, an environment map or a rig (or drop one on the window)")
    if app.panel.show_browser:
        _, app.panel.plate_next = imgui.checkbox("the next photo opened is the plate", app.panel.plate_next)
        remember(app, "plate next")
        if imgui.is_item_hovered():
            imgui.set_tooltip("a background photo (chosen below, or dropped on the window) to put the person into:\n"
                              "they stand on its ground, lit by its light, their shadow on it")
        chosen = app.browser.draw(lambda name: remember(app, f"browser {name}"))
        if chosen is not None:
            app.actions.open_file(chosen)


def _plate(app):
    """The plate the person is put into, when there is one: where they stand, the camera's
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
        remember(app, "light from the plate")
        if imgui.is_item_hovered():
            imgui.set_tooltip("the person lit by the plate's own light (a map made from it) in place of the map's")
        imgui.same_line()
    if imgui.button("remove the plate"):
        app.actions.remove_plate()
    remember(app, "remove the plate")


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
    remember(app, "thumbnail")
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
        c = swatch(kelvin_to_rgb(p.kelvin), 2.0)
        centre = imgui.ImVec2(lo.x + u * size.x, lo.y + v * size.y)
        draw.add_circle_filled(centre, 5.0, imgui.get_color_u32(c))
        draw.add_circle(centre, 5.0, imgui.get_color_u32(imgui.ImVec4(0.0, 0.0, 0.0, 1.0)))
        draw.add_text(imgui.ImVec2(centre.x + 6.0, centre.y - 7.0), ring, str(first + j))


def _record(app):
    from viewer.app.recording import InteractionRecording

    if not imgui.collapsing_header("Record", section_open(app, False)):
        return
    rec = app.recording
    if rec is None:
        if imgui.button("Record clip (R)" if app.timeline is not None else "Record (R)"):
            app.recorder.toggle_recording("live")
        remember(app, "record")
        imgui.same_line()
        if imgui.button("360 turn (T)"):
            app.recorder.toggle_recording("turntable")
        remember(app, "record turn")
        imgui.same_line()
        if imgui.button("Save frame (S)"):
            app.recorder.save_frame()
        imgui.set_next_item_width(120)
        changed, frames = imgui.slider_int("turn frames", app.recorder.turn_frames, 12, 720)
        if changed:
            app.recorder.set_turn_frames(frames)
    elif isinstance(rec, InteractionRecording) and rec.capturing:
        imgui.text(f"recording what you do: {rec.seconds:.1f} s")
        if imgui.button("Stop and render (R)"):
            app.recorder.toggle_recording(rec.kind)
        remember(app, "record")
    else:
        left = rec.time_left.words()
        imgui.progress_bar(rec.fraction, imgui.ImVec2(-1, 0), f"{rec.done} / {rec.total} frames" + (f", {left}" if left else ""))
        if imgui.button("Stop"):
            app.recorder.toggle_recording(rec.kind)
        remember(app, "record")
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
