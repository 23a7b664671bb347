"""The house rules, checked on the code: no import cycles, the product never imports the lab,
docs/architecture.md's module map is current, and one validated settings type (``Look``)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from viewer.errors import InputError
from viewer.lab.modules import LAB, LAYERS, cycles, folder_problems, import_graph, markdown, modules
from viewer.scene.look import PRESET_NAMES, Look

ROOT = Path(__file__).resolve().parents[1]


def test_no_import_cycles():
    assert cycles(import_graph()) == []


def test_folders_depend_one_way_and_downwards():
    """The folder-level graph of every import (inside functions and under TYPE_CHECKING too): no
    two folders import each other, and no arrow climbs the layers (viewer.lab.modules.LAYERS)."""
    assert folder_problems(import_graph()) == []
    assert set(LAYERS) >= {".".join(m.split(".")[:2]) for m in modules() if m.count(".") >= 2}


def test_folder_problems_are_found():
    graph = {"viewer.scene.bundle": {"viewer.photo.frame"}, "viewer.photo.frame": {"viewer.scene.bundle"},
             "viewer.files.imageio": {"viewer.gl.engine"}, "viewer.gl.engine": set()}
    problems = folder_problems(graph)
    assert any("import each other" in p for p in problems)
    assert any("viewer.files -> viewer.gl climbs" in p for p in problems)


def test_product_file_names_are_unique_and_the_root_is_small():
    """No two modules of the product share a file name; at most ten loose modules at the root."""
    product = [m for m in modules() if not (m == LAB or m.startswith(LAB + ".")) and not m.endswith("__init__")]
    names = [m.rsplit(".", 1)[-1] for m in product if m.count(".") >= 1 and m not in LAYERS]
    assert sorted({n for n in names if names.count(n) > 1}) == []
    assert len([m for m in product if m.count(".") == 1 and m not in LAYERS]) <= 10


def test_the_house_rules_hold():
    """Files, app classes, cli files and the engine within their lines, no function over ten parameters,
    one resize, no module named after its folder, no run file tracked, every docs file named
    (viewer.lab.house_rules)."""
    from viewer.lab.house_rules import problems

    assert problems() == []


def test_house_rule_breaches_are_found():
    from viewer.lab.house_rules import _parameters, repository_problems

    tracked = ["README.md", "docs/architecture.md", "docs/orphan.png", "render.pid", "out/.x.mp4.relight-lock"]
    found = repository_problems(tracked)
    assert found == ["render.pid: a run file, tracked", "out/.x.mp4.relight-lock: a run file, tracked",
                     "docs/orphan.png: no page names it"]
    import ast

    fn = ast.parse("def f(self, a, b, c, d, e, f, g, h, i, j, *k, **m): pass").body[0]
    assert _parameters(fn) == 12


def test_cycles_are_found():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_product_module_imports_the_lab():
    graph = import_graph()
    assert len(graph) > 80
    crossing = [(a, b) for a, deps in graph.items() for b in deps
                if not (a == LAB or a.startswith(LAB + ".")) and (b == LAB or b.startswith(LAB + "."))]
    assert crossing == []


def test_the_module_map_in_the_docs_is_current():
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert markdown() in text, "run: python -m viewer.lab.modules --write docs/architecture.md"


def test_no_shared_data_path_inside_the_package():
    offenders = [str(p.relative_to(ROOT)) for p in (ROOT / "viewer").rglob("*.py")
                 if '"shared"' in p.read_text(encoding="utf-8") or "parents[2].parent" in p.read_text(encoding="utf-8")]
    assert offenders == []


def test_preset_names_match_the_presets():
    from viewer.gl.presets import DEFAULT_PRESET, PRESETS

    assert PRESET_NAMES == tuple(PRESETS) and Look().preset == DEFAULT_PRESET


@pytest.mark.parametrize("changes, field", [
    ({"yaw": math.nan}, "yaw"), ({"tilt": math.inf}, "tilt"), ({"exposure": 41.0}, "exposure"),
    ({"exposure": "bright"}, "exposure"), ({"tonemap": "filmic"}, "tone map"), ({"background": "sky"}, "background"),
    ({"background_color": (1.0, -1.0, 0.0)}, "background colour"), ({"shadows": "soft-ish"}, "shadows"),
    ({"view": "x"}, "view"), ({"light": -1}, "light"), ({"intensity": -2.0}, "intensity"),
    ({"preset": "ultra"}, "preset"),
])
def test_a_bad_look_is_one_line_naming_the_field(changes, field):
    with pytest.raises(InputError) as err:
        Look(**changes)
    assert str(err.value).startswith(field) and "\n" not in str(err.value)


def test_looks_round_trip_and_old_state_files_load(tmp_path):
    look = Look(yaw=30.0, tilt=-10.0, exposure=1.5, tonemap="reinhard", background="color", background_color=(0.1, 0.2, 0.3),
                shadows="hard", diffuse=False, view="shadow", light=2, intensity=2.0, preset="final")
    assert Look.from_json(json.loads(json.dumps(look.to_json()))) == look
    # what the viewer's state file held before the one settings type (no background, no preset)
    old = {"yaw": 12.0, "tilt": 0.0, "exposure": -0.5, "intensity": 1.0, "shadows": "refined", "diffuse": True,
           "specular": True, "view": "final", "light": 0}
    assert Look.from_json(old) == Look(yaw=12.0, exposure=-0.5, shadows="refined")
    assert Look.from_json({"visibility": "none", "unknown": 1}).shadows == "none"
    with pytest.raises(InputError, match="state.json: exposure"):
        Look.from_json({"exposure": float("nan")}, where="state.json")


def test_the_command_line_names_the_option(tmp_path, capsys):
    from viewer.cli.main import main

    env = ROOT / "assets" / "envmaps" / "venice_sunset_256.hdr"
    scene = ROOT / "assets" / "sample_scene"
    assert main(["render", str(scene), "--env", str(env), "--yaw", "nan", "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert "--yaw: yaw must be a finite number" in err and err.count("\n") == 1
    assert main(["render", str(scene), "--env", str(env), "--exposure", "50", "-o", str(tmp_path / "x.png")]) == 2
    assert "--exposure:" in capsys.readouterr().err
    bad = tmp_path / "look.json"
    bad.write_bytes(b"\xff\xfe{")
    assert main(["render", str(scene), "--env", str(env), "--look", str(bad), "-o", str(tmp_path / "x.png")]) == 2
    assert "look.json: not a JSON look file" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


def test_a_saved_look_renders_what_the_options_render(tmp_path):
    """``--look`` with a frame's saved JSON gives the same pixels as the same options spelled out;
    an option given beside it wins."""
    from viewer.cli.main import main
    from viewer.files.imageio import read_png

    env = ROOT / "assets" / "envmaps" / "venice_sunset_256.hdr"
    lights = ROOT / "assets" / "envmaps" / "venice_sunset_256.lights.json"
    scene = ROOT / "assets" / "sample_scene"
    saved = tmp_path / "capture.json"
    saved.write_text(json.dumps({"look": Look(yaw=60.0, exposure=0.5, tonemap="reinhard", shadows="hard").to_json(),
                                 "map": str(env)}))
    common = ["render", str(scene), str(lights), "--env", str(env), "--size", "128"]
    assert main(common + ["--look", str(saved), "-o", str(tmp_path / "a.png")]) == 0
    assert main(common + ["--yaw", "60", "--exposure", "0.5", "--tonemap", "reinhard", "--visibility", "hard",
                          "-o", str(tmp_path / "b.png")]) == 0
    assert main(common + ["--look", str(saved), "--exposure", "-1", "-o", str(tmp_path / "c.png")]) == 0
    a, b, c = (read_png(tmp_path / f"{k}.png") for k in "abc")
    assert (a == b).all() and c.mean() < a.mean() - 0.02


def test_the_lab_commands_are_listed_but_not_imported():
    import subprocess
    import sys

    code = ("import sys; from viewer.cli.parser import build_parser, command_plugins; "
            "build_parser(command_plugins()).print_help(); print(sorted(m for m in sys.modules if m.startswith('viewer.lab')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert all(f"    {name}" in out for name in ("bench", "dataset", "train")) and out.strip().endswith("[]")


def test_a_look_saved_with_more_lights_fits_fewer():
    look = Look(view="shadow", light=12, intensity=2.0)
    assert look.fitted(16) is look
    assert look.fitted(8) == Look(view="final", light=0, intensity=2.0)
    assert Look(view="albedo", light=12).fitted(4).view == "albedo"


def test_a_saved_looks_intensity_and_selected_light_are_rendered(tmp_path):
    """A capture saved at x2 intensity renders brighter than at x1; one whose selected light is
    past the light file's count renders (the relit image) instead of failing."""
    from viewer.cli.main import main
    from viewer.files.imageio import read_exr

    env = ROOT / "assets" / "envmaps" / "venice_sunset_256.hdr"
    lights = ROOT / "assets" / "envmaps" / "venice_sunset_256.lights.json"
    scene = ROOT / "assets" / "sample_scene"
    hdr = {}
    for k, look in {"one": Look(exposure=0.0), "two": Look(exposure=0.0, intensity=2.0, view="shadow", light=40)}.items():
        saved = tmp_path / f"{k}.json"
        saved.write_text(json.dumps({"look": look.to_json()}))
        assert main(["render", str(scene), str(lights), "--env", str(env), "--size", "96", "--background", "transparent",
                     "--look", str(saved), "-o", str(tmp_path / f"{k}.png")]) == 0
        hdr[k] = read_exr(tmp_path / f"{k}.exr")
    person = hdr["one"][..., :3].sum(axis=-1) > 0
    ratio = hdr["two"][..., :3][person].sum() / hdr["one"][..., :3][person].sum()
    assert 1.9 < ratio < 2.1
