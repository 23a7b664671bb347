"""A small file browser drawn in the panel (works on any machine: no system dialog needed)."""

from __future__ import annotations

from pathlib import Path

from imgui_bundle import imgui


class FileBrowser:
    def __init__(self, start: Path, suffixes=(".hdr", ".exr")):
        self.dir = Path(start).resolve()
        self.suffixes = tuple(suffixes)
        self.path_text = ""

    def _entries(self):
        try:
            items = sorted(self.dir.iterdir(), key=lambda p: (not p.is_dir(), p.name.lower()))
        except OSError:
            return []
        return [p for p in items if not p.name.startswith(".") and (p.is_dir() or p.suffix.lower() in self.suffixes)]

    def draw(self) -> Path | None:
        """Draw the browser; returns a file the user chose this frame."""
        chosen = None
        imgui.text_wrapped(str(self.dir))
        imgui.begin_child("files", imgui.ImVec2(0, 140), imgui.ChildFlags_.borders)
        if imgui.selectable("..", False)[0]:
            self.dir = self.dir.parent
        for entry in self._entries():
            label = f"[{entry.name}]" if entry.is_dir() else entry.name
            if imgui.selectable(label, False)[0]:
                if entry.is_dir():
                    self.dir = entry
                else:
                    chosen = entry
        imgui.end_child()
        imgui.set_next_item_width(-60)
        _, self.path_text = imgui.input_text("##path", self.path_text)
        imgui.same_line()
        if imgui.button("Open") and self.path_text.strip():
            p = Path(self.path_text.strip()).expanduser()
            if p.is_dir():
                self.dir = p.resolve()
            else:
                chosen = p
        return chosen
