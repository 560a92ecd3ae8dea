"""Non-finite or invalid scene data is bad input (issue 10, defect 3): exit code 2 with one
line naming the key, before anything is assembled or solved — not a solve that ends in
"diverged_function_nanorinf" (exit 1) or, for k ≤ 0, a meaningless "solution" (exit 0)."""

from __future__ import annotations

from pathlib import Path

import contact as ct
from contact.setup.build import build_problem

import numpy as np
import pytest
from clirun import ROOT, contact, error_lines, small_scene

# (--set override, start of the message after "contact: error: ")
CLI_CASES = [
    ("data.f=1/0", "data.f: 1 / 0 divides by zero"),
    ("data.g=log(x-2)", "data.g: not a finite number at 9 of 9 nodes, e.g. at x = 0, y = 0"),
    ("data.u_D=sqrt(-1)", "data.u_D: sqrt(-1) is undefined"),
    ("data.t_C=(-8)**(1/3)", "data.t_C: (-8) ** (1 / 3) is not a real number"),
    (
        "solver.u0=sqrt(x - 0.5)",
        "solver.u0: not a finite number at 36 of 81 nodes, e.g. at x = 0, y = 0",
    ),
    ("data.k=-1", "data.k: must be > 0 at 81 of 81 nodes, e.g. at x = 0, y = 0 (got -1)"),
]


RUNS = [(0, *case) for case in CLI_CASES] + [
    (2, *case) for case in CLI_CASES if case[0][:6] in ("data.g", "data.k")
]


@pytest.mark.parametrize("ranks, override, expect", RUNS, ids=[f"{r or 1}-{o}" for r, o, _ in RUNS])
def test_cli_bad_data_is_exit_2(tmp_path: Path, override: str, expect: str, ranks: int) -> None:
    small_scene(tmp_path / "scene.yaml")
    proc = contact(tmp_path, "run", "scene.yaml", "-o", "out", "--set", override, ranks=ranks)
    assert proc.returncode == 2, proc.stderr + proc.stdout
    lines = error_lines(proc)
    assert len(lines) == 1 and lines[0].startswith(f"contact: error: {expect}"), proc.stderr
    assert "DoFs" not in proc.stdout and " it " not in proc.stdout  # nothing was solved
    assert not (tmp_path / "out").exists()


def _square(**data) -> dict:
    import yaml

    scene = yaml.safe_load((ROOT / "configs" / "signorini_square.yaml").read_text())
    scene["mesh"]["cells"] = [4, 4]
    scene["data"].update(data)
    return scene


@pytest.mark.parametrize(
    "data, expect",
    [
        ({"t": "1/(x - 0.5)"}, None),  # used on the sides x = 0, 1 only: fine
        ({"g": "0.1 if y < 0.5 else log(x - 2)"}, None),  # used on y = 0 only: fine
        ({"t": "1/(x - 1)"}, "data.t: not a finite number at 5 of 10 nodes, e.g. at x = 1, y = 0"),
        ({"f": "1/(x*y)"}, "data.f: not a finite number at 9 of 25 nodes, e.g. at x = 0, y = 0"),
        ({"exact": "sqrt(y - 0.5)"}, "data.exact: not a finite number at 10 of 25 nodes"),
        (
            {"k": "x - 0.5"},
            "data.k: must be > 0 at 15 of 25 nodes, e.g. at x = 0, y = 0 (got -0.5)",
        ),
        (
            {"k": "1/(x - 0.5)"},
            "data.k: not a finite number at 5 of 25 nodes, e.g. at x = 0.5, y = 0",
        ),
    ],
)
def test_scalar_data_checked_where_used(data: dict, expect: str | None) -> None:
    scene = ct.load_scene(_square(**data))
    if expect is None:
        build_problem(scene)
        return
    with pytest.raises(
        ct.ConfigError,
        match="^" + expect.replace("(", r"\(").replace(")", r"\)").replace("*", r"\*"),
    ):
        build_problem(scene)


@pytest.mark.parametrize("once", [True, False])
def test_the_points_of_a_role_are_gathered_once(monkeypatch, once: bool) -> None:
    """The data of a role are evaluated at its vertices gathered once (every vertex: a
    read-only view of the geometry; ``POINTS_ONCE``) or copied per datum (the old path):
    the same reports, the geometry untouched."""
    from contact.setup import checks

    monkeypatch.setattr(checks, "POINTS_ONCE", once)
    seen: list = []
    to_numpy = checks.expressions.to_numpy

    def spy(*args, **kwargs):
        f = to_numpy(*args, **kwargs)
        return lambda x: seen.append(x) or f(x)

    monkeypatch.setattr(checks.expressions, "to_numpy", spy)
    scene = ct.load_scene(_square(f="x*y", k="1/(x - 0.5)"))
    x = scene.mesh.geometry.x.copy()
    with pytest.raises(ct.ConfigError, match=r"^data\.k: not a finite number at 5 of 25 nodes"):
        checks.check_scene_data(scene)
    assert np.array_equal(scene.mesh.geometry.x, x)
    everywhere = [p for p in seen if p.shape[1] == 25]  # f and k at every vertex
    assert len(everywhere) == 2 and np.array_equal(everywhere[0], everywhere[1])
    shared = np.shares_memory(everywhere[0], scene.mesh.geometry.x)
    assert shared == once and (everywhere[0] is everywhere[1]) == once


def test_obstacle_psi_checked_everywhere() -> None:
    scene = _square(psi="log(x)")
    scene["model"] = "obstacle"
    scene["boundaries"].pop("bottom")
    scene["data"].pop("g")
    with pytest.raises(ct.ConfigError, match=r"^data\.psi: not a finite number at 5 of 25 nodes"):
        build_problem(ct.load_scene(scene))


HERTZ = ["mesh.h=0.2", "mesh.h_contact=0.05", "adapt.max_levels=1"]


@pytest.mark.parametrize(
    "override, expect",
    [
        ("data.f=['0', 'log(x - 0.5)']", r"^data\.f\[1\]: not a finite number at \d+ of \d+ nodes"),
        (
            "data.u_D=['0', '-delta/(x - 0)']",
            r"^data\.u_D\[1\]: not a finite number at 1 of \d+ nodes, e\.g\. at x = 0, y = 1",
        ),
        ("model.E=0", r"^model\.E: must be > 0, got 0"),
        ("model.nu=-1", r"^model\.nu: must lie in \(-1, 0\.5\), got -1"),
    ],
)
def test_elasticity_data_checked(override: str, expect: str) -> None:
    with pytest.raises(ct.ConfigError, match=expect):
        build_problem(ct.load_scene(ROOT / "configs" / "hertz_2d.yaml", [*HERTZ, override]))


def test_negative_poisson_ratio_is_allowed() -> None:
    config = ct.load_scene(ROOT / "configs" / "hertz_2d.yaml", [*HERTZ, "model.nu=-0.5"]).config
    assert config.model.nu == -0.5


def test_u0_checked_in_the_api() -> None:
    raw = _square()
    raw["solver"]["u0"] = "1/(y - 0.25)"
    with pytest.raises(ct.ConfigError, match=r"^solver\.u0: not a finite number at 5 of 25 nodes"):
        ct.solve(ct.load_scene(raw), verbose=False)
