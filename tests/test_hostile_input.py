"""Hostile or runaway input fails fast in one line (issue 10, defects 2 and 8): YAML alias
bombs, oversized scene and study files, expressions too long or too deep, constants that
cannot be evaluated.  Each case runs the real CLI; each must answer within seconds."""

from __future__ import annotations

import time
from pathlib import Path

import contact as ct
from contact.base import expressions
from contact.setup.config import MAX_YAML_NODES, YAMLTooLarge, load_yaml

import pytest
from clirun import contact, error_lines, small_scene


def alias_bomb(levels: int, width: int = 9) -> str:
    """``[&a0 [1, …], &a1 [*a0, …], …, *a{levels-1}]``: width**levels items in a few
    hundred bytes, as the value of mesh.cells."""
    items = [f"&a0 [{', '.join(['8'] * width)}]"]
    items += [f"&a{i} [{', '.join([f'*a{i - 1}'] * width)}]" for i in range(1, levels)]
    return f"[{', '.join(items + [f'*a{levels - 1}'])}]"


def _scene_text(cells: str) -> str:
    return (
        f"name: bomb\nmesh: {{type: unit_square, cells: {cells}}}\n"
        "boundaries: {bottom: {role: contact, where: 'y < 1e-10'}, top: {role: dirichlet, "
        "where: 'y > 0.9'}}\n"
    )


def _fails_fast(tmp: Path, *args: str, expect: str, limit: float = 30.0) -> str:
    t0 = time.perf_counter()
    proc = contact(tmp, *args)
    assert time.perf_counter() - t0 < limit
    lines = error_lines(proc)
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and len(lines[0]) <= 300, f"{len(proc.stderr)} characters on stderr"
    assert lines[0].startswith("contact: error: " + expect), lines[0]
    return lines[0]


@pytest.mark.parametrize("levels, width", [(9, 9), (7, 8)])  # 9**9 = 387 M and 8**7 = 2 M items
def test_yaml_alias_bomb_in_mesh_cells(tmp_path: Path, levels: int, width: int) -> None:
    text = _scene_text(alias_bomb(levels, width))
    assert len(text) < 1000
    (tmp_path / "bomb.yaml").write_text(text)
    _fails_fast(
        tmp_path,
        "run",
        "bomb.yaml",
        expect=f"bomb.yaml: the YAML document expands to more than {MAX_YAML_NODES} nodes",
    )


def test_yaml_alias_bomb_in_a_study(tmp_path: Path) -> None:
    small_scene(tmp_path / "scene.yaml")
    (tmp_path / "study.yaml").write_text(f"scene: scene.yaml\naxes: {{level: {alias_bomb(9)}}}\n")
    _fails_fast(tmp_path, "study", "study.yaml", expect="study.yaml: the YAML document expands")


def test_yaml_bomb_in_a_set_value_is_not_expanded() -> None:
    with pytest.raises(ct.ConfigError, match=r"^mesh\.cells: must be a positive integer"):
        ct.load_scene(
            {"mesh": {"type": "unit_square"}, "boundaries": {}}, [f"mesh.cells={alias_bomb(9)}"]
        )


def test_recursive_alias_and_deep_nesting() -> None:
    with pytest.raises(YAMLTooLarge, match="recursive alias"):
        load_yaml("a: &x [1, *x]\n")
    with pytest.raises(YAMLTooLarge, match="nested too deeply"):
        load_yaml("a: " + "[" * 5000 + "]" * 5000)
    assert load_yaml("a: &x [1, 2]\nb: [*x, *x]\n") == {"a": [1, 2], "b": [[1, 2], [1, 2]]}


@pytest.mark.parametrize("kind", ["run", "study"])
def test_files_over_one_megabyte_are_refused(tmp_path: Path, kind: str) -> None:
    small_scene(tmp_path / "scene.yaml")
    big = tmp_path / f"{kind}.yaml"
    text = (tmp_path / "scene.yaml").read_text() if kind == "run" else "scene: scene.yaml\n"
    big.write_text(text + ("# padding " + "x" * 90 + "\n") * 20_000)  # 2 MB of comments
    _fails_fast(
        tmp_path,
        kind,
        big.name,
        expect=f"{big.name}: the file has {big.stat().st_size} bytes, more than "
        "the limit of 1000000",
        limit=20,
    )


# ------------------------------------------------------------------------- expressions
EXPRESSION_CASES = {
    "200000 terms": (
        "+".join(["x"] * 200_000),
        "data.exact: the expression has 399999 characters, more than the limit of 10000",
    ),
    "5000-deep power": ("**".join(["2"] * 5000), "data.exact: the expression has 14998 characters"),
    "3000-deep power": ("**".join(["x"] * 3000), "data.exact: cannot parse 'x**x**"),
    "deep sum": (
        "+".join(["x"] * 2000),
        "data.exact: the expression nests 2002 levels deep, more than the limit of 100",
    ),
    "1/0": ("1/0", "data.exact: 1 / 0 divides by zero"),
    "2**10000": ("2**10000", "data.exact: 2 ** 10000 overflows"),
    "(-1)**0.5": ("(-1)**0.5", "data.exact: (-1) ** 0.5 is not a real number"),
}


@pytest.mark.parametrize(
    "text, expect", list(EXPRESSION_CASES.values()), ids=list(EXPRESSION_CASES)
)
def test_expression_limits_and_constants_on_the_cli(tmp_path: Path, text: str, expect: str) -> None:
    small_scene(tmp_path / "scene.yaml", data__exact=text)
    _fails_fast(tmp_path, "run", "scene.yaml", expect=expect)


@pytest.mark.parametrize(
    "text, message",
    [
        ("-" * 150 + "x", "nests 153 levels deep"),
        ("+".join(["x"] * 150), "nests 152 levels deep"),
        ("sin(" * 120 + "x" + ")" * 120, "nests 123 levels deep"),
        ("log(0)", "log(0) is undefined"),
        ("exp(1000) * x", "exp(1000) overflows"),
        ("1e400", "1e309 is not a finite number"),
        ("x + 10**400", "10 ** 400 overflows"),
    ],
)
def test_parse_limits(text: str, message: str) -> None:
    with pytest.raises(
        expressions.ExpressionError,
        match=message.replace("(", r"\(")
        .replace(")", r"\)")
        .replace("*", r"\*")
        .replace("+", r"\+"),
    ):
        expressions.parse(text)


def test_limits_leave_ordinary_expressions_alone() -> None:
    for text in [
        "r**(2/3)*sin(2/3*(atan2(y, x) + (2*pi if atan2(y, x) < -pi/4 else 0)))",
        "x if x < 0 else 1/x",
        "sqrt(x)",
        "log(x - 2)",
        "+".join(["x"] * 90),
        "-(-(-x))",
    ]:
        tree = expressions.parse(text)
        assert tree is not None


# ------------------------------------------------------------------------- issue 26
def test_a_billion_load_steps_are_refused_at_once(tmp_path: Path) -> None:
    """load.steps: 10⁹ built a list of 10⁹ pseudo-times while checking the scene (11.5 GB in
    60 s); the bound is MAX_LOAD_STEPS, as long as the longest explicit ``times`` list."""
    small_scene(tmp_path / "scene.yaml", load={"steps": 1_000_000_000})
    _fails_fast(
        tmp_path,
        "run",
        "scene.yaml",
        limit=20,
        expect="load.steps: must be at most 100000 (the longest load path), got 1000000000",
    )
    assert ct.setup.config.MAX_LOAD_STEPS == 100_000 and ct.setup.config.MAX_YAML_NODES == 100_000


@pytest.mark.parametrize("where", ["study", "scene of a study"])
def test_duplicate_keys_in_study_files(tmp_path: Path, where: str) -> None:
    """A key given twice (the last one won silently) is one error line naming its path."""
    scene = small_scene(tmp_path / "scene.yaml")
    if where == "study":
        text = "scene: scene.yaml\naxes:\n  method: [fb]\n  method: [min]\n"
        (tmp_path / "study.yaml").write_text(text)
        expect = "study.yaml: duplicate key axes.method (lines 3 and 4)"
    else:
        scene.write_text(scene.read_text() + "solver: {method: min}\n")
        (tmp_path / "study.yaml").write_text("scene: scene.yaml\naxes: {line_search: [basic]}\n")
        expect = f"{scene}: duplicate key solver"
    _fails_fast(tmp_path, "study", "study.yaml", expect=expect)
