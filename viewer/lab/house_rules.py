"""The house's size and naming rules, counted on the code (``python -m viewer.lab.house_rules`` prints
the figures; ``tests/test_architecture.py`` fails on any breach):

- no product file over ``MAX_FILE`` lines, a ``cli/`` file over ``MAX_CLI``, the engine's file over
  ``MAX_ENGINE``, a class of the window (``app/``) over ``MAX_APP_CLASS``;
- no product function taking more than ``MAX_PARAMETERS`` parameters (``self`` not counted): a longer
  list is the options object it is (a look, a clip request, a plate spot);
- images resized only by ``viewer/resize.py`` (``cv2.resize`` nowhere else);
- no module named after its own folder (``plate/plate_sky.py`` is ``plate/sky.py``);
- no run files tracked (``*.pid``, ``*.log``, partial videos, lock files), and every file in ``docs/``
  named by a page (the README or a ``docs/*.md``).

The product is ``viewer/`` without the lab (``viewer/lab/``, which the product never imports)."""

from __future__ import annotations

import ast
import fnmatch
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "viewer"
MAX_FILE = 500
MAX_CLI = 350
MAX_ENGINE = 350
MAX_APP_CLASS = 250
MAX_PARAMETERS = 10
RESIZE_HOME = PACKAGE / "resize.py"
RUN_FILES = ("*.pid", "*.log", "*.partial.mp4", ".*.relight-lock")
OPENCV_RESIZE = "cv2." + "resize("  # (spelt in two so that this file does not hold it)


def product_files() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if p.relative_to(PACKAGE).parts[0] != "lab")


def _lines(path: Path) -> int:
    return len(path.read_text(encoding="utf-8").splitlines())


def _parameters(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = node.args
    n = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + (a.vararg is not None) + (a.kwarg is not None)
    first = (a.posonlyargs + a.args)[:1]
    return n - (1 if first and first[0].arg in ("self", "cls") else 0)


def size_problems() -> list[str]:
    """Files, classes and parameter lists past the limits (module docstring)."""
    out = []
    for path in product_files():
        rel, n = path.relative_to(ROOT), _lines(path)
        limit = MAX_CLI if path.parent.name == "cli" else MAX_ENGINE if path == PACKAGE / "gl" / "engine.py" else MAX_FILE
        if n > limit:
            out.append(f"{rel}: {n} lines (at most {limit})")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef) and path.parent.name == "app":
                size = node.end_lineno - node.lineno + 1
                if size > MAX_APP_CLASS:
                    out.append(f"{rel}: class {node.name} {size} lines (at most {MAX_APP_CLASS})")
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and _parameters(node) > MAX_PARAMETERS:
                out.append(f"{rel}: {node.name}() takes {_parameters(node)} parameters (at most {MAX_PARAMETERS})")
    return out


def naming_problems() -> list[str]:
    """``cv2.resize`` outside ``viewer/resize.py`` (the lab's included) and modules named after their folder."""
    out = [f"{p.relative_to(ROOT)}: cv2.resize (resize with viewer.resize.resize)" for p in sorted(PACKAGE.rglob("*.py"))
           if p != RESIZE_HOME and OPENCV_RESIZE in p.read_text(encoding="utf-8")]
    for path in product_files():
        folder, stem = path.parent.name, path.stem
        if path.parent != PACKAGE and (stem == folder or stem.startswith(folder + "_") or stem.startswith(folder.rstrip("s") + "_")):
            out.append(f"{path.relative_to(ROOT)}: named after its folder")
    return out


def tracked_files() -> list[str]:
    return subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()


def repository_problems(tracked: list[str] | None = None) -> list[str]:
    """Run files tracked, and files in ``docs/`` that no page names."""
    tracked = tracked_files() if tracked is None else tracked
    out = [f"{f}: a run file, tracked" for f in tracked if any(fnmatch.fnmatch(Path(f).name, g) for g in RUN_FILES)]
    pages = "\n".join((ROOT / f).read_text(encoding="utf-8") for f in tracked
                      if f == "README.md" or (f.startswith("docs/") and f.endswith(".md")))
    out += [f"{f}: no page names it" for f in tracked
            if f.startswith("docs/") and not f.endswith(".md") and Path(f).name not in pages]
    return out


def problems() -> list[str]:
    return size_problems() + naming_problems() + repository_problems()


def figures() -> dict:
    """The counts the rules bound (the largest of each), for the docs and the session's notes."""
    files = product_files()
    largest = max(files, key=_lines)
    functions = [(node.name, _parameters(node), p) for p in files for node in ast.walk(ast.parse(p.read_text(encoding="utf-8")))
                 if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))]
    name, params, where = max(functions, key=lambda f: f[1])
    app_classes = [(node.name, node.end_lineno - node.lineno + 1) for p in files if p.parent.name == "app"
                   for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))) if isinstance(node, ast.ClassDef)]
    return {"product_files": len(files), "largest_file": [str(largest.relative_to(ROOT)), _lines(largest)],
            "largest_app_class": list(max(app_classes, key=lambda c: c[1])),
            "most_parameters": [f"{where.relative_to(ROOT)}:{name}", params],
            "largest_cli_file": max(_lines(p) for p in files if p.parent.name == "cli"),
            "engine_file": _lines(PACKAGE / "gl" / "engine.py"), "problems": len(problems())}


if __name__ == "__main__":
    import json

    for line in problems():
        print(line)
    print(json.dumps(figures(), indent=1))
    sys.exit(1 if problems() else 0)
