"""The side panel's lighting sections: the map's longitude, tilt and exposure, each light's size and
intensity (sigma shown as the light's angular size in degrees), and the lights you place."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from imgui_bundle import imgui

from viewer.app.interaction import exposed
from viewer.app.panel_state import remember, section_open
from viewer.app.session import BACKGROUND_NAMES
from viewer.lighting.median_cut import LUMINANCE
from viewer.lighting.placed_lights import MAX_SIZE, RIGS, PlacedLight, free_spot, kelvin_to_rgb
from viewer.scene.area_lights import azimuth_elevation
from viewer.scene.shadow_space import ANGULAR_SIGMA

LIGHT_COUNT_SLIDER = 64  # the map's lights the slider offers (the final preset's count; a light file holds up to area_lights.MAX_LIGHTS)
SIGMA_SLIDER = 30.0  # the size sliders' top, sigma units (the fits give at most light_size.SIGMA_MAX, 20)
DEG_PER_SIGMA = math.degrees(ANGULAR_SIGMA)  # the slider shows a light's size: its angular sigma in degrees


def swatch(intensity: np.ndarray, peak: float) -> imgui.ImVec4:
    c = np.clip(intensity / max(peak, 1e-30), 0, 1) ** (1 / 2.2)
    return imgui.ImVec4(float(c[0]), float(c[1]), float(c[2]), 1.0)


def lighting_section(app):
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
    remember(app, "longitude")
    if changed:
        s.update(yaw=yaw)
    changed, tilt = imgui.slider_float("tilt", v.tilt, -90.0, 90.0, "%.1f deg")
    remember(app, "tilt")
    if changed:
        s.update(tilt=tilt)
    # the slider leaves room for "level" (the photo's brightness under the lights now) and its label
    level = imgui.calc_text_size("level").x + 2 * imgui.get_style().frame_padding.x + imgui.get_style().item_spacing.x
    imgui.set_next_item_width(imgui.calc_item_width() - level)
    changed, exposure = imgui.slider_float("##exposure", v.exposure_stops, -10.0, 10.0, "%+.2f stops")
    remember(app, "exposure")
    if changed:
        s.look = exposed(s.look, exposure)
    imgui.same_line()
    if imgui.button("level"):
        app.actions.level_exposure()
    if imgui.is_item_hovered():
        imgui.set_tooltip("expose for the photo's brightness under the lights now\n(a new map keeps the exposure you had)")
    remember(app, "level exposure")
    imgui.same_line(0, imgui.get_style().item_inner_spacing.x)
    imgui.text("exposure")
    changed, intensity = imgui.slider_float("map##intensity", v.intensity, 0.0, 8.0, "map's lights x %.2f",
                                            imgui.SliderFlags_.logarithmic)
    remember(app, "intensity")
    if changed:
        s.update(intensity=intensity)
    if s.scene.frame is not None:  # before / after: the original photo left of the split (B toggles)
        changed, compare = imgui.slider_float("before | after", v.compare, 0.0, 1.0,
                                              "photo %.2f" if v.compare > 0.0 else "off")
        remember(app, "compare")
        if changed:
            s.update(compare=compare)
    changed, ground = imgui.checkbox("ground shadow (G)", held.ground if held is not None else s.ground_shown)
    remember(app, "ground")
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
    remember(app, "behind")
    if imgui.is_item_hovered():
        imgui.set_tooltip("behind the person: the map, the photo's own background (shown as it is, whatever the\n"
                          "exposure), or a grey")
    if changed:
        s.update(background=BACKGROUND_NAMES[names[i]])


def lights_section(app):
    held = app.held  # a new map or person coming in: the picture's lights, not to be changed meanwhile
    n = len(held.sigma if held is not None else app.session.sigma)
    if not imgui.collapsing_header(f"Area lights ({n})", section_open(app, False)):
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
    remember(app, "number of lights")
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
        imgui.color_button("##c", swatch(lights.intensity[i], peak), 0, imgui.ImVec2(18, 18))
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
        remember(app, f"sigma {i}")
        if changed:
            s.set_sigma(i, size / DEG_PER_SIGMA)
        imgui.pop_id()
    imgui.end_child()
    imgui.push_text_wrap_pos(0.0)
    imgui.text_disabled("click a light to see its shadow; sorted by brightness")
    imgui.pop_text_wrap_pos()
    remember(app, "lights hint")


def placed_section(app):
    """The user's own lights: a rig, add, edit (direction, size, intensity, colour temperature),
    delete, undo and redo, save the rig."""
    s = app.session
    if not imgui.collapsing_header(f"Your lights ({len(s.placed)})", section_open(app, False)):
        return
    level = app.actions.placed_level()
    # always drawn (greyed out without lights of yours), here with them: a rig that adds the first
    # light moves nothing (the map's thumbnail and "open a file" took clicks meant for each other)
    imgui.begin_disabled(not s.placed)
    changed, placed_level = imgui.slider_float("yours", s.look.placed_intensity, 0.0, 8.0,
                                               "all x %.2f" if s.placed else "none yet", imgui.SliderFlags_.logarithmic)
    imgui.end_disabled()
    remember(app, "placed intensity")
    if changed and s.placed:
        s.update(placed_intensity=placed_level)
    names = list(RIGS)
    imgui.set_next_item_width(140)
    _, app.panel.rig_choice = imgui.combo("##rig", app.panel.rig_choice, names)
    imgui.same_line()
    if imgui.button("use rig"):
        app.actions.use_rig(names[app.panel.rig_choice])
    remember(app, "use rig")
    imgui.same_line()
    if imgui.button("add light"):
        azimuth, elevation = free_spot(s.placed)  # not on top of a light already there
        s.set_placed(s.placed + (PlacedLight(azimuth, elevation, intensity=level),))
    remember(app, "add light")
    _, s.keep_absolute = imgui.checkbox("keep absolute intensities", s.keep_absolute)
    remember(app, "keep absolute")
    if imgui.is_item_hovered():
        imgui.set_tooltip("on: your lights keep their intensities when the map changes\n"
                          "off: they keep their share of the light (scaled with the map's brightness)")
    if imgui.button("undo"):  # short labels: the row fits the narrowest panel (the keys in the tooltips)
        s.undo()
    if imgui.is_item_hovered():
        imgui.set_tooltip("Ctrl+Z")
    remember(app, "undo")
    imgui.same_line()
    if imgui.button("redo"):
        s.redo()
    if imgui.is_item_hovered():
        imgui.set_tooltip("Ctrl+Y")
    remember(app, "redo")
    imgui.same_line()
    if imgui.button("save rig") and s.placed:
        app.actions.save_rig()
    remember(app, "save rig")
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
        imgui.color_button("##c", swatch(kelvin_to_rgb(p.kelvin), 2.0), 0, imgui.ImVec2(18, 18))
        imgui.same_line()
        imgui.text(f"yours {j + 1} (light {len(s.base_lights) + j})")
        imgui.same_line()
        if imgui.small_button("aim"):
            app.actions.start_aiming(j)
        remember(app, f"placed {j} aim")
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
            remember(app, f"placed {j} {name}")
            if imgui.is_item_activated():  # one undo step per drag of a slider
                s.history.record(s.placed)
            if changed:
                edits[name] = value
        if edits:
            placed[j] = replace(p, **edits)
            s.set_placed(placed, record=False)
        imgui.pop_id()

    imgui.end_child()
