"""The package's module map, read from the code: every ``import`` of every module (top-level and
inside functions) as a graph, its cycles, and the picture of it in ``docs/architecture.md``.

``python -m viewer.lab.modules`` prints the generated part of docs/architecture.md;
``--write docs/architecture.md`` replaces it there (between the ``modules:begin`` and
``modules:end`` markers). ``tests/test_architecture.py`` checks that the file is current, that
there are no import cycles and that no product module imports the lab.
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from pathlib import Path

PACKAGE = "viewer"
LAB = "viewer.lab"
BEGIN, END = "<!-- modules:begin (python -m viewer.lab.modules --write docs/architecture.md) -->", "<!-- modules:end -->"
# the stages of the picture: a module belongs to the group of the longest prefix it starts with
GROUPS = (
    ("lab", ("viewer.lab",), "datasets, ground truth, training, benchmarks"),
    ("cli", ("viewer.cli",), "the relight command"),
    ("app", ("viewer.app",), "the viewer window: input, panel, session, jobs, recording"),
    ("output", ("viewer.output",), "headless frames, layers for compositors, MP4, temporal metrics"),
    ("batch", ("viewer.batch",), "photos x looks on worker processes or a Ray cluster, the manifest, resumable"),
    ("plate", ("viewer.plate",), "a background photo to put the person into: its camera, its light as an HDR map"),
    ("photo", ("viewer.photo", "viewer.nets"), "photo to scene bundle: its frame, the matte, the networks, the face, refinement"),
    ("engine", ("viewer.gl", "viewer.shader_modes"), "GL passes, programs, context, the shaders' modes"),
    ("twin", ("viewer.twin",), "the engine in differentiable torch"),
    ("lighting", ("viewer.lighting",), "environment maps, light fitting, your lights, where a map's lights come from"),
    ("scene", ("viewer.scene",), "scene bundle, camera, geometry, the ground, area lights, the Look, presets, the backdrop"),
    ("files", ("viewer.files",), "files in standard formats, what a given file is, what this program wrote"),
    ("base", ("viewer",), "errors, assets, constants, progress, memory needs, cores, signals"),
)


def package_root() -> Path:
    return Path(__file__).resolve().parents[1]


def modules(root: Path | None = None) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package."""
    root = root or package_root()
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = (PACKAGE,) + path.relative_to(root).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def import_graph(root: Path | None = None) -> dict[str, set[str]]:
    """Module -> the package's modules it imports (anywhere in its body)."""
    mods = modules(root)
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[:len(package.split(".")) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                for alias in node.names:
                    full = f"{target}.{alias.name}"
                    deps.add(full if full in mods else target)
            elif isinstance(node, ast.Import):
                deps.update(alias.name for alias in node.names)
        graph[name] = {d for d in deps if d in mods and d != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(graph) + 100))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def group_of(name: str) -> str:
    """The group of a module (the one whose prefix matches it longest)."""
    best, length = "base", -1
    for group, prefixes, _ in GROUPS:
        for prefix in prefixes:
            if (name == prefix or name.startswith(prefix + ".")) and len(prefix) > length:
                best, length = group, len(prefix)
    return best


SENTENCE_END = re.compile(r"(?<![0-9])(?<!\bal)(?<!e\.g)(?<!i\.e)(?<!\bvs)\.\s+(?=[A-Z(`*])")


def summary(path: Path) -> str:
    """The first sentence of a module's docstring, whole: a full stop ends it when a capital follows
    and it does not close a number ("Step 5."), "et al." or "e.g."."""
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    first = " ".join(doc.split("\n\n")[0].split())
    return SENTENCE_END.split(first, maxsplit=1)[0].rstrip(".") if first else ""


# The folders, bottom first: a folder imports only folders below it (tests/test_architecture.py)
LAYERS = ("viewer", "viewer.files", "viewer.scene", "viewer.twin", "viewer.lighting", "viewer.gl", "viewer.nets",
          "viewer.photo", "viewer.plate", "viewer.output", "viewer.batch", "viewer.app", "viewer.cli", "viewer.lab")


def folder_of(name: str) -> str:
    """The folder (a package directly under ``viewer``, or the root's loose modules) a module is in."""
    parts = name.split(".")
    folder = ".".join(parts[:2])
    return folder if len(parts) > 2 or folder in LAYERS else PACKAGE


def folder_graph(graph: dict[str, set[str]]) -> dict[tuple[str, str], list[tuple[str, str]]]:
    """(folder, folder it imports) -> the module imports behind the arrow, from every import of
    :func:`import_graph` (those inside functions and under ``TYPE_CHECKING`` included)."""
    out: dict[tuple[str, str], list[tuple[str, str]]] = {}
    for a, deps in graph.items():
        for b in deps:
            fa, fb = folder_of(a), folder_of(b)
            if fa != fb:
                out.setdefault((fa, fb), []).append((a, b))
    return out


def folder_problems(graph: dict[str, set[str]]) -> list[str]:
    """Two-way pairs of folders and arrows that climb ``LAYERS`` (a folder missing from it climbs)."""
    arrows = folder_graph(graph)
    rank = {f: i for i, f in enumerate(LAYERS)}
    out = []
    for (a, b), why in sorted(arrows.items()):
        if (b, a) in arrows and a < b:
            out.append(f"{a} and {b} import each other ({why[0][0]} -> {why[0][1]}; "
                       f"{arrows[(b, a)][0][0]} -> {arrows[(b, a)][0][1]})")
        if rank.get(a, -1) <= rank.get(b, len(LAYERS)):
            out.append(f"{a} -> {b} climbs ({why[0][0]} imports {why[0][1]})")
    return out


def markdown(root: Path | None = None) -> str:
    """The generated part of docs/architecture.md: the group picture (Mermaid) and the module table."""
    mods = modules(root)
    graph = import_graph(root)
    edges = sorted({(group_of(a), group_of(b)) for a, deps in graph.items() for b in deps if group_of(a) != group_of(b)})
    lines = [BEGIN, "", "```mermaid", "flowchart TD"]
    lines += [f'    {group}["<b>{group}</b><br/>{what}"]' for group, _, what in GROUPS]
    lines += [f"    {a} --> {b}" for a, b in edges]
    lines += ["```", "", f"{len(mods)} modules, {sum(len(d) for d in graph.values())} imports between them, "
              f"{len(cycles(graph))} import cycles. An arrow reads \"imports\".", "",
              "| group | module | what it is | imports (in the package) |", "|---|---|---|---|"]
    order = {group: i for i, (group, _, _) in enumerate(GROUPS)}
    for name in sorted(mods, key=lambda m: (order[group_of(m)], m)):
        deps = ", ".join(sorted(d.removeprefix("viewer.") for d in graph[name])) or "-"
        lines.append(f"| {group_of(name)} | `{name}` | {summary(mods[name])} | {deps} |")
    lines += ["", END]
    return "\n".join(lines)


def update(doc: Path, root: Path | None = None) -> bool:
    """Replace the generated part of ``doc``; True if it changed."""
    from viewer.files.imageio import write_text

    text = doc.read_text(encoding="utf-8")
    start, end = text.index(BEGIN), text.index(END) + len(END)
    new = text[:start] + markdown(root) + text[end:]
    if new != text:
        write_text(doc, new)
    return new != text


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m viewer.lab.modules", description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", help="the Markdown file whose generated part to replace (docs/architecture.md)")
    args = parser.parse_args(argv)
    if args.write:
        print(f"{'updated' if update(Path(args.write)) else 'unchanged'}: {args.write}")
    else:
        print(markdown())
    return 0


if __name__ == "__main__":
    sys.exit(main())
