"""Bad input to ``contact run`` fails before any solve: exit code 2, one stderr line
``contact: error: <key path or file>: <what is wrong>``, no traceback, no output folder.

Every case runs the CLI as a subprocess (``python -m contact.app.cli run ...``) in its own tmp
directory, on scenes derived from configs/signorini_square.yaml with an 8 × 8 mesh.
"""

from __future__ import annotations

import copy
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import make_square_msh

ROOT = Path(__file__).resolve().parents[1]
PREFIX = "contact: error: "
METHODS = "fb, min, blend, vinewtonrsls, vinewtonssls"
DELETE = object()


def _base_scene() -> dict:
    scene = yaml.safe_load((ROOT / "configs" / "signorini_square.yaml").read_text())
    scene["mesh"]["cells"] = [8, 8]
    return scene


GMSH_SCENE = {
    "name": "gmsh_square",
    "mesh": {"type": "gmsh", "file": "square.msh"},
    "boundaries": {
        "top": {"role": "dirichlet", "tag": 2},
        "sides": {"role": "neumann", "tag": 3},
        "bottom": {"role": "contact", "tag": 1},
    },
    "model": "signorini",
    "data": {"f": "1", "g": "0.1 + 2*(x - 0.5)**2"},
}


@dataclass
class Case:
    """A bad input: ``changes`` (dotted path → value, DELETE removes the key) applied to
    ``base``, or ``text`` written verbatim as the scene file; ``expect`` is the start of
    the message after ``contact: error: `` (``{scene}``/``{tmp}`` are filled in)."""

    expect: str
    changes: dict = field(default_factory=dict)
    text: str | bytes | None = None
    base: str = "square"  # square | gmsh
    args: tuple = ()
    contains: str = ""
    scene: str | None = None  # scene argument if not the written file (relative to tmp)
    msh: bool = False  # copy the small gmsh mesh into tmp (as square.msh)
    output: bool = True  # pass -o tmp/out


def _apply(scene: dict, changes: dict) -> dict:
    scene = copy.deepcopy(scene)
    for key, value in changes.items():
        node, parts = scene, key.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        if value is DELETE:
            del node[parts[-1]]
        else:
            node[parts[-1]] = value
    return scene


CASES = {
    # --- unknown keys -----------------------------------------------------------------
    "unknown_top_key": Case("colour: unknown key (expected one of name, mesh,", {"colour": "red"}),
    "unknown_solver_key": Case(
        "solver.methd: unknown key (expected one of method, mu,", {"solver.methd": "fb"}
    ),
    "unknown_boundary_key": Case(
        "boundaries.bottom.wher: unknown key", {"boundaries.bottom.wher": "y < 0"}
    ),
    "unknown_data_key": Case("data.q: unknown key", {"data.q": "1"}),
    "mesh_key_unused_by_type": Case(
        "mesh.corners: not used by mesh type 'unit_square'", {"mesh.corners": [[0, 0], [1, 1]]}
    ),
    "gmsh_with_cells": Case(
        "mesh.cells: not used by mesh type 'gmsh'", {"mesh.cells": 8}, base="gmsh", msh=True
    ),
    # --- wrong types ------------------------------------------------------------------
    "mu_string": Case("solver.mu: expected a number, got a string 'half'", {"solver.mu": "half"}),
    "rtol_bool": Case("solver.rtol: expected a number, got a boolean True", {"solver.rtol": True}),
    "max_it_float": Case(
        "solver.max_it: expected an integer, got a number 2.5", {"solver.max_it": 2.5}
    ),
    "section_not_mapping": Case("solver: expected a mapping, got a string 'fb'", {"solver": "fb"}),
    "boundaries_list": Case(
        "boundaries: expected a mapping, got a list", {"boundaries": ["top", "bottom"]}
    ),
    "cells_string": Case("mesh.cells: must be a positive integer or a list", {"mesh.cells": "8x8"}),
    "where_number": Case(
        "boundaries.bottom.where: expected a string", {"boundaries.bottom.where": 0}
    ),
    "tag_string": Case(
        "boundaries.bottom.tag: expected an integer",
        {"boundaries.bottom.tag": "one"},
        base="gmsh",
        msh=True,
    ),
    "verbose_string": Case("output.verbose: expected true or false", {"output.verbose": "loud"}),
    "constant_string": Case("constants.a: expected a number", {"constants": {"a": "b"}}),
    "constant_bad_name": Case(
        "constants.x: is not a usable constant name", {"constants": {"x": 1}}
    ),
    "petsc_option_list": Case(
        "solver.petsc_options.ksp_type: must be a string, number or boolean",
        {"solver.petsc_options": {"ksp_type": [1, 2]}},
    ),
    # --- not one of the choices -------------------------------------------------------
    "method_choice": Case(
        f"solver.method: 'fbb' is not one of {METHODS}", {"solver.method": "fbb"}
    ),
    "role_choice": Case(
        "boundaries.bottom.role: 'contakt' is not one of dirichlet, neumann, contact",
        {"boundaries.bottom.role": "contakt"},
    ),
    "model_choice": Case(
        "model.type: 'elastic' is not one of signorini, obstacle", {"model": "elastic"}
    ),
    "mesh_type_choice": Case("mesh.type: 'circle' is not one of", {"mesh.type": "circle"}),
    "line_search_choice": Case(
        "solver.line_search: 'cp' is not one of auto, basic, bt", {"solver.line_search": "cp"}
    ),
    # --- out of range -----------------------------------------------------------------
    "mu_one": Case("solver.mu: must lie in (0, 1), got 1.0", {"solver.mu": 1}),
    "mu_zero": Case("solver.mu: must lie in (0, 1), got 0.0", {"solver.mu": 0}),
    "mu_negative": Case("solver.mu: must lie in (0, 1), got -0.5", {"solver.mu": -0.5}),
    "mu_nan": Case("solver.mu: must be finite, got nan", {"solver.mu": float("nan")}),
    "rtol_negative": Case("solver.rtol: must be >= 0, got -1e-08", {"solver.rtol": -1e-8}),
    "atol_negative": Case("solver.atol: must be >= 0, got -1.0", {"solver.atol": -1}),
    "c_negative": Case("solver.c: must be > 0, got -1", {"solver.c": -1}),
    "c_string": Case(
        "solver.c: must be 'auto' or a positive number, got 'big'", {"solver.c": "big"}
    ),
    "c_infinite": Case(
        "solver.c: must be 'auto' or a positive number, got inf", {"solver.c": float("inf")}
    ),
    # --- impossible parameters --------------------------------------------------------
    "cells_zero": Case(
        "mesh.cells: must be a positive integer or a list of positive integers, got 0",
        {"mesh.cells": 0},
    ),
    "cells_list_zero": Case("mesh.cells: must be a positive integer", {"mesh.cells": [8, 0]}),
    "cells_wrong_count": Case(
        "mesh.cells: a unit_square mesh needs 2 cell count(s), got [8, 8, 8]",
        {"mesh.cells": [8, 8, 8]},
    ),
    "max_it_zero": Case("solver.max_it: must be > 0, got 0", {"solver.max_it": 0}),
    "degree_three": Case("mesh.degree: 3 is not one of 1, 2", {"mesh.degree": 3}),
    "residual_p2_obstacle_3d": Case(
        "estimator: residual does not converge with a P2 obstacle solution in 3D",
        {
            "model": "obstacle",
            "mesh.type": "box",
            "mesh.corners": [[0, 0, 0], [1, 1, 1]],
            "mesh.cells": [2, 2, 2],
            "mesh.degree": 2,
            "estimator": "residual",
            "boundaries.bottom": DELETE,
            "data.g": DELETE,
            "data.psi": "-1",
        },
    ),
    "corners_reversed": Case(
        "mesh.corners: the second corner must exceed the first in every coordinate",
        {"mesh.type": "rectangle", "mesh.corners": [[1, 1], [0, 0]]},
    ),
    "corners_3d_for_rectangle": Case(
        "mesh.corners: a rectangle needs 2D points",
        {"mesh.type": "rectangle", "mesh.corners": [[0, 0, 0], [1, 1, 1]]},
    ),
    "corners_infinite": Case(
        "mesh.corners: coordinates must be finite",
        {"mesh.type": "rectangle", "mesh.corners": [[0, 0], [float("inf"), 1]]},
    ),
    "map_wrong_count": Case(
        "mesh.map: expected 2 expressions for a 2D mesh, got 3", {"mesh.map": ["x", "y", "z"]}
    ),
    "map_not_a_list": Case(
        "mesh.map: expected a list of expressions, one per coordinate, got a string",
        {"mesh.map": "x + y"},
    ),
    "map_bad_expression": Case("mesh.map[1]: unknown name 'q'", {"mesh.map": ["x + y", "q*y"]}),
    # a fold at x = 0.5
    "map_inverts_cells": Case(
        "mesh.map: the map inverts or flattens 64 of 128 cells",
        {"mesh.map": ["x if x < 0.5 else 1 - x", "y"]},
    ),
    "map_flattens_cells": Case(
        "mesh.map: the map inverts or flattens 128 of 128 cells", {"mesh.map": ["x", "0"]}
    ),
    "map_not_finite": Case(
        "mesh.map[0]: not a finite number at 9 of 81 vertices", {"mesh.map": ["log(x)", "y"]}
    ),
    "map_of_gmsh_mesh": Case(
        "mesh.map: not used by mesh type 'gmsh'", {"mesh.map": ["x", "y"]}, base="gmsh", msh=True
    ),
    "bound_lower_signorini": Case(
        "model.bound: Signorini contact is always",
        {"model": {"type": "signorini", "bound": "lower"}},
    ),
    "psi_for_signorini": Case("data.psi: only for model type obstacle", {"data.psi": "0"}),
    # --- files ------------------------------------------------------------------------
    "missing_scene_file": Case("{tmp}/nope.yaml: no such file", scene="nope.yaml"),
    "scene_is_directory": Case("{tmp}: no such file", scene="."),
    "malformed_yaml": Case(
        "{scene}: malformed YAML (line 2, column 15): mapping values are not allowed",
        text="name: x\nsolver: method: fb\n",
    ),
    "yaml_unclosed_brace": Case("{scene}: malformed YAML", text="name: x\nsolver: {method: fb\n"),
    "yaml_tab_indent": Case("{scene}: malformed YAML", text="mesh:\n\ttype: unit_square\n"),
    "yaml_python_tag": Case(
        "{scene}: malformed YAML", text="name: !!python/object/apply:os.system ['true']\n"
    ),
    "yaml_not_mapping": Case(
        "{scene}: expected a mapping of sections at the top level, got a list",
        text="- mesh\n- solver\n",
    ),
    "yaml_empty": Case(
        "{scene}: expected a mapping of sections at the top level, got empty", text=""
    ),
    "yaml_not_utf8": Case("{scene}: not UTF-8 text", text=b"name: \xff\xfe\n"),
    # issue 26: PyYAML keeps the last of two equal keys silently
    "yaml_duplicate_key": Case(
        "{scene}: duplicate key name (lines 1 and 3); give each key once",
        text="name: a\nmesh: {type: unit_square}\nname: b\n",
    ),
    "yaml_duplicate_nested_key": Case(
        "{scene}: duplicate key boundaries.bottom.where (lines 4 and 5)",
        text="mesh: {type: unit_square}\nboundaries:\n  bottom:\n"
        "    where: 'y < 0'\n    where: 'y < 1e-10'\n    role: contact\n",
    ),
    "yaml_duplicate_in_list": Case(
        "{scene}: duplicate key mesh.blocks[1].cells (lines 2 and 2)",
        text="mesh: {type: blocks, blocks: [{cells: 1},\n  {cells: 2, cells: 3}]}\n",
    ),
    "set_duplicate_key": Case(
        "--set solver: duplicate key method (lines 1 and 1)",
        args=("--set", "solver={method: fb, method: min}"),
    ),
    "missing_mesh_file": Case(
        "mesh.file: no such file '{tmp}/nope.msh'", {"mesh.file": "nope.msh"}, base="gmsh"
    ),
    "gmsh_without_file": Case(
        "mesh.file: required for mesh type 'gmsh'", {"mesh.file": DELETE}, base="gmsh"
    ),
    "corrupt_mesh_file": Case(
        "mesh.file: cannot read '{tmp}/garbage.msh' as a gmsh mesh",
        {"mesh.file": "garbage.msh"},
        base="gmsh",
    ),
    # --- boundary parts ---------------------------------------------------------------
    "where_selects_nothing": Case(
        "boundaries.bottom: where 'y < -1' selects no boundary facet",
        {"boundaries.bottom.where": "y < -1"},
    ),
    "where_interior_only": Case(
        "boundaries.bottom: where 'abs(y - 0.5) < 1e-10' selects no boundary facet",
        {"boundaries.bottom.where": "abs(y - 0.5) < 1e-10"},
    ),
    "tag_missing_in_msh": Case(
        "boundaries.bottom.tag: tag 99 does not exist in the mesh file (facet tags: 1, 2, 3)",
        {"boundaries.bottom.tag": 99},
        base="gmsh",
        msh=True,
    ),
    "tag_of_surface_group": Case(
        "boundaries.bottom.tag: tag 10 does not exist in the mesh file",
        {"boundaries.bottom.tag": 10},
        base="gmsh",
        msh=True,
    ),
    "tag_without_gmsh": Case(
        "boundaries.bottom.tag: tags need a gmsh mesh",
        {"boundaries.bottom": {"role": "contact", "tag": 1}},
    ),
    "where_and_tag_select_nothing": Case(
        "boundaries.bottom: tag 1 and where 'y > 2' selects no boundary facet",
        {"boundaries.bottom.where": "y > 2"},
        base="gmsh",
        msh=True,
    ),
    "neither_where_nor_tag": Case(
        "boundaries.bottom: give 'where' or 'tag'", {"boundaries.bottom": {"role": "contact"}}
    ),
    "role_missing": Case(
        "boundaries.bottom.role: required key is missing",
        {"boundaries.bottom": {"where": "y < 1e-10"}},
    ),
    "overlapping_parts": Case(
        "boundaries: sides and bottom share",
        {"boundaries.sides.where": "x < 1e-10 or x > 1 - 1e-10 or y < 1e-10"},
        contains="parts must not overlap",
    ),
    # Two overlapping pairs (top/bottom, sides/left): the first pair in the file's order is
    # named, not the first two names in alphabetical order ("bottom and left").
    "two_overlapping_pairs": Case(
        "boundaries: top and bottom share",
        {
            "boundaries.bottom.where": "y < 1e-10 or y > 1 - 1e-10",
            "boundaries.left": {"role": "neumann", "where": "x < 1e-10"},
        },
        contains="parts must not overlap",
    ),
    "no_boundaries": Case("boundaries: at least one boundary part is required", {"boundaries": {}}),
    "no_contact_part": Case(
        "boundaries: a signorini scene needs a part with role: contact",
        {"boundaries.bottom": DELETE},
    ),
    # --- expressions ------------------------------------------------------------------
    "expr_import": Case("data.f: only the functions sin, cos,", {"data.f": "__import__('os')"}),
    "expr_attribute": Case("data.g: attribute is not allowed", {"data.g": "x.__class__"}),
    "expr_unknown_name": Case("data.g: unknown name 'foo'", {"data.g": "foo * x"}),
    "expr_not_whitelisted_function": Case("data.u_D: only the functions", {"data.u_D": "floor(x)"}),
    "expr_eval": Case("data.t: only the functions", {"data.t": "eval('1')"}),
    "expr_lambda": Case("data.f: only the functions", {"data.f": "(lambda: 0)()"}),
    "expr_syntax": Case("data.u_D: cannot parse 'x +'", {"data.u_D": "x +"}),
    "expr_string_constant": Case("data.f: constant 'abc' is not a number", {"data.f": "'abc'"}),
    "expr_bare_function": Case(
        "data.f: 'sin' is a function, call it with arguments", {"data.f": "sin"}
    ),
    "expr_arity": Case("data.g: atan2() takes 2 argument(s)", {"data.g": "atan2(x)"}),
    "expr_empty": Case("data.g: empty expression", {"data.g": " "}),
    "expr_u0": Case("solver.u0: cannot parse", {"solver.u0": "import os"}),
    "where_call": Case(
        "boundaries.bottom.where: only the functions", {"boundaries.bottom.where": "os.system('x')"}
    ),
    "where_syntax": Case(
        "boundaries.bottom.where: cannot parse", {"boundaries.bottom.where": "y <"}
    ),
    "where_unknown_name": Case(
        "boundaries.top.where: unknown name 'Y'", {"boundaries.top.where": "Y > 1"}
    ),
    # --- command line -----------------------------------------------------------------
    "set_without_equals": Case(
        "--set solver.method: expected KEY.PATH=VALUE", args=("--set", "solver.method")
    ),
    "set_empty_key": Case("--set =3: expected KEY.PATH=VALUE", args=("--set", "=3")),
    "set_empty_part": Case(
        "--set solver..mu=0.5: expected KEY.PATH=VALUE", args=("--set", "solver..mu=0.5")
    ),
    "set_into_value": Case(
        "--set mesh.cells.x: cells is not a section", args=("--set", "mesh.cells.x=3")
    ),
    "set_missing_value": Case("argument --set: expected one argument", args=("--set",)),
    "set_out_of_range": Case(
        "solver.mu: must lie in (0, 1), got 2.0", args=("--set", "solver.mu=2")
    ),
    "set_unknown_key": Case("solver.metod: unknown key", args=("--set", "solver.metod=fb")),
    "set_bad_choice": Case(
        f"solver.method: 'fbb' is not one of {METHODS}", args=("--set", "solver.method=fbb")
    ),
    "unknown_option": Case("unrecognized arguments: --frobnicate", args=("--frobnicate",)),
    "error_without_output_option": Case(
        "solver.mu: must lie in (0, 1)", {"solver.mu": 5}, output=False
    ),
    "output_option_empty": Case(
        "-o: the output folder must not be empty", output=False, args=("-o", "")
    ),
    "output_dir_empty": Case("output.dir: must not be empty", {"output.dir": " "}, output=False),
}


@pytest.fixture(scope="module")
def square_msh(tmp_path_factory) -> Path:
    """A gmsh mesh of the unit square: facet groups bottom 1, top 2, sides 3; surface 10."""
    return make_square_msh(tmp_path_factory.mktemp("gmsh") / "square.msh", size=0.25)


def _contact(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONWARNINGS": "ignore", "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, "-m", "contact.app.cli", "run", *args],
        cwd=tmp,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


def _snapshot(tmp: Path) -> set[str]:
    """Every entry below tmp, hidden ones included."""
    return {str(p.relative_to(tmp)) for p in tmp.rglob("*")}


@pytest.mark.parametrize("case", list(CASES.values()), ids=list(CASES))
def test_bad_input_fails_before_solve(case: Case, tmp_path: Path, request) -> None:
    tmp_path = tmp_path.resolve()
    scene_file = tmp_path / "scene.yaml"
    if case.text is not None:
        if isinstance(case.text, bytes):
            scene_file.write_bytes(case.text)
        else:
            scene_file.write_text(case.text)
    elif case.scene is None:
        base = _base_scene() if case.base == "square" else copy.deepcopy(GMSH_SCENE)
        scene_file.write_text(yaml.safe_dump(_apply(base, case.changes), sort_keys=False))
    if case.msh:
        (tmp_path / "square.msh").write_bytes(request.getfixturevalue("square_msh").read_bytes())
    if "garbage.msh" in str(case.changes):
        (tmp_path / "garbage.msh").write_text("this is not a gmsh file\n")
    before = _snapshot(tmp_path)

    scene_arg = str(tmp_path / case.scene) if case.scene is not None else str(scene_file)
    out = tmp_path / "out"
    proc = _contact(tmp_path, scene_arg, *(["-o", str(out)] if case.output else []), *case.args)

    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2, (
        f"exit code {proc.returncode}\nstderr:\n{proc.stderr}\nstdout:\n{proc.stdout}"
    )
    assert "Traceback" not in proc.stderr + proc.stdout
    assert len(lines) == 1, f"expected one stderr line, got:\n{proc.stderr}"
    line = lines[0]
    assert line.startswith(PREFIX), line
    message = line[len(PREFIX) :]
    expect = case.expect.format(scene=scene_file, tmp=tmp_path)
    assert message.startswith(expect), f"\n got: {message}\nwant: {expect}..."
    assert case.contains in message
    assert not out.exists(), "output folder was created"
    assert _snapshot(tmp_path) == before, "files or folders were created in the run directory"


def test_valid_small_scene_writes_output(tmp_path: Path) -> None:
    scene_file = tmp_path / "scene.yaml"
    scene = _base_scene()
    scene["mesh"]["cells"] = [16, 16]  # 8 × 8: 3 nodes in contact, a warning (test_progress.py)
    scene_file.write_text(yaml.safe_dump(scene, sort_keys=False))
    out = tmp_path / "out"
    proc = _contact(tmp_path, str(scene_file), "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    assert not [ln for ln in proc.stderr.splitlines() if ln.strip()], proc.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [
            ".contact-result",
            "solution.h5",
            "solution.vtu",
            "solution.xdmf",
            "contact_surface.h5",
            "contact_surface.xdmf",
            "summary.json",
            "history.csv",
            "solution.png",
            "contact.csv",
            "pressure.png",
        ]
    )
    assert all(
        (out / name).stat().st_size > 0 for name in ("solution.vtu", "summary.json", "solution.png")
    )
    # the atomic write leaves no hidden .out.partial-*/.out.old-* sibling behind
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "scene.yaml"]


@pytest.mark.parametrize(
    "text, value",
    [
        ("1e6", 1e6),
        ("1E-3", 1e-3),
        ("-2.5e+4", -2.5e4),
        ("3", 3),
        ("1.0", 1.0),
        ("1e6x", "1e6x"),
        ("fb", "fb"),
    ],
)
def test_yaml_reads_exponent_floats(text: str, value: Any) -> None:
    """`--set solver.kappa=1e6` and `kappa: 1e6` are numbers (PyYAML alone reads a string)."""
    from contact.setup.config import apply_overrides, load_yaml

    assert load_yaml(f"k: {text}") == {"k": value}
    assert apply_overrides({}, [f"solver.kappa={text}"]) == {"solver": {"kappa": value}}


# ------------------------------------------------------------ every message: one short line
def _plain_cli(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    """The CLI with Python's default warnings (not the suite's PYTHONWARNINGS=ignore): a
    library's warning would show on stderr as a user sees it."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    return subprocess.run(
        [sys.executable, "-m", "contact.app.cli", *args],
        cwd=tmp,
        env={**env, "OMP_NUM_THREADS": "1"},
        capture_output=True,
        text=True,
        timeout=600,
    )


INDENT = str(ROOT / "configs" / "hyperelastic_indentation.yaml")
SQUARE = str(ROOT / "configs" / "signorini_square.yaml")
SMALL = ("--set", "mesh.cells=[8,4]", "--set", "output.png=false")
#: (exit code, start of the line, arguments): bad input and failures of every kind
BATTERY = [
    (2, "contact: error: solver.methd: unknown key", (SQUARE, "--set", "solver.methd=fb")),
    (
        2,
        "contact: error: load.cuts: must be at most 20",
        (INDENT, *SMALL, "--set", "load.cuts=1000000"),
    ),
    (2, "contact: error: data.f: not a finite number", (SQUARE, "--set", "data.f=sqrt(x - 2)")),
    (
        2,
        "contact: error: obstacle.center[1] (at t = 0.6): not a finite number (inf)",
        (INDENT, *SMALL, "--set", 'obstacle.center=[0, "R - delta*t + 1/(t - 0.6)"]'),
    ),
    (
        2,
        "contact: error: obstacle.center[1] (at t = 0.6): not a finite number (nan)",
        (INDENT, *SMALL, "--set", 'obstacle.center=[0, "R - delta*t + sqrt(0.5 - t)"]'),
    ),
    (2, "contact: error: ", ("missing.yaml",)),
    (1, "contact: error: solver fb did not converge", (SQUARE, "--set", "solver.max_it=1")),
    (
        1,  # a load path failing at step 3 after 4 cuts, K_T indefinite from step 2
        "contact: error: step 3 (t = 0.4125) did not converge (diverged_function_nanorinf)",
        (INDENT, *SMALL, "--set", 'obstacle.center=[0, "R - delta*t + log(1 - t)"]'),
    ),
]


@pytest.mark.parametrize("code, start, args", BATTERY, ids=[b[1][16:40] for b in BATTERY])
def test_every_message_is_one_line_of_at_most_300_characters(tmp_path, code, start, args):
    """Bad input and failures of the solver through the CLI, warnings shown as Python shows
    them by default: stderr is exactly one line, ours, of at most 300 characters (no numpy
    RuntimeWarning with its source line: a non-finite obstacle is named by its key and t,
    not met by the contact search), and a failed load path keeps its last words: which
    steps were kept where."""
    proc = _plain_cli(tmp_path, "run", *args, "-o", "out", "-q")
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == code and len(lines) == 1, proc.stderr
    assert lines[0].startswith(start) and len(lines[0]) <= 300, lines[0]
    assert "Warning" not in proc.stderr
    if code == 1 and "step" in start:
        assert lines[0].endswith("kept steps 1-2 in out/ (summary.json: converged false)")


def test_warnings_print_as_one_line(capsys):
    """The CLI prints any warning — the project's and a library's — as one line of at most
    300 characters, not Python's two (the message and its source line)."""
    import warnings

    from contact.app.cli import one_line_warning
    from contact.setup.surfaces import ContactWarning

    one_line_warning("zone too small " * 40, ContactWarning, "x.py", 3)
    one_line_warning("invalid value encountered in divide", RuntimeWarning, "/a/b/obst.py", 284)
    lines = capsys.readouterr().err.splitlines()
    assert lines[0].startswith("contact: warning: zone too small") and len(lines[0]) == 300
    assert lines[1] == (
        "contact: warning: RuntimeWarning: invalid value encountered in divide (obst.py:284)"
    )
    assert len(lines) == 2 and warnings.showwarning is not one_line_warning
