"""A small file browser drawn in the panel (works on any machine: no system dialog needed). A scene
bundle's folder (one holding scene.json) is listed as something to open, not to enter."""

from __future__ import annotations

from pathlib import Path

from imgui_bundle import imgui


def is_bundle(path: Path) -> bool:
    return path.is_dir() and (path / "scene.json").is_file()


class FileBrowser:
    def __init__(self, start: Path, suffixes=(".hdr", ".exr")):
        self.dir = Path(start).resolve()
        self.suffixes = tuple(suffixes)
        self.path_text = ""
        self.selected: Path | None = None  # the entry one click chose: its path in the field, opened by Enter or Open

    def _entries(self):
        try:
            items = sorted(self.dir.iterdir(), key=lambda p: (not p.is_dir(), p.name.lower()))
        except OSError:
            return []
        return [p for p in items if not p.name.startswith(".") and (p.is_dir() or p.suffix.lower() in self.suffixes)]

    def draw(self, remember=lambda name: None) -> Path | None:
        """Draw the browser; returns a file (or a bundle's folder) the user chose this frame. One
        click on an entry selects it (its path goes into the field); a double click, or Enter or
        Open after it, opens it (a folder: enters it), so a click that lands on a wrong entry opens
        nothing. ``remember(name)`` is called after the path field and its button (scripts click them)."""
        chosen = None
        imgui.text_wrapped(str(self.dir))
        imgui.begin_child("files", imgui.ImVec2(0, 140), imgui.ChildFlags_.borders)
        if imgui.selectable("..", False, imgui.SelectableFlags_.allow_double_click)[0] and imgui.is_mouse_double_clicked(0):
            self.dir = self.dir.parent
        for entry in self._entries():
            bundle = is_bundle(entry)
            label = f"{entry.name} (scene bundle)" if bundle else f"[{entry.name}]" if entry.is_dir() else entry.name
            if imgui.selectable(label, entry == self.selected, imgui.SelectableFlags_.allow_double_click)[0]:
                self.selected, self.path_text = entry, str(entry)
                if imgui.is_mouse_double_clicked(0):
                    chosen = self._open(entry)
        imgui.end_child()
        imgui.set_next_item_width(-60)
        # a click selects the whole path, so what is typed replaces it; Enter opens it
        flags = imgui.InputTextFlags_.auto_select_all | imgui.InputTextFlags_.enter_returns_true
        entered, self.path_text = imgui.input_text("##path", self.path_text, flags)
        remember("path")
        imgui.same_line()
        if (imgui.button("Open") or entered) and self.path_text.strip():
            chosen = self._open(Path(self.path_text.strip()).expanduser())
        remember("open")
        return chosen

    def _open(self, p: Path) -> Path | None:
        """A folder is entered (nothing chosen); a file or a bundle's folder is chosen."""
        if p.is_dir() and not is_bundle(p):
            self.dir, self.selected, self.path_text = p.resolve(), None, ""
            return None
        return p
