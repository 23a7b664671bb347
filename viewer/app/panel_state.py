"""What the side panel keeps between frames (:class:`PanelState`), where each widget it drew is
(:func:`remember`: the state file's ``widgets``, and the IDs two widgets share) and how its sections
open (:func:`section_open`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from imgui_bundle import imgui

from viewer.app.layout import SMALL_HEIGHT


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


def remember(app, name: str):
    """Where the widget just drawn is (the state file's ``widgets``), and whether its imgui ID is
    another widget's this frame: two widgets with one ID take each other's clicks (the map chooser
    would never open beside the "map" intensity slider); the state file lists them."""
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


def section_open(app, first: bool) -> int:
    """The flag for a section's header: expanded on a tall window, or when ``first`` (the section a
    small window shows); a section the user opened or closed stays as they left it."""
    return imgui.TreeNodeFlags_.default_open if first or app.window.size[1] >= SMALL_HEIGHT else 0
