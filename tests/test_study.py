"""The study runner (issue 5): ``contact study STUDY.yaml`` runs a sweep and writes
study.csv / levels.csv / study.json and its charts; failing runs are rows classified by
outcome, bad study files fail before anything runs (exit 2, one line); 2 MPI ranks give
the serial iteration counts."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
SQUARE = ROOT / "configs" / "signorini_square.yaml"
FREE = ROOT / "configs" / "signorini_free_boundary.yaml"
MPIRUN = Path(sys.executable).parent / "mpirun"
PREFIX = "contact: error: "
ENV = {**os.environ, "PYTHONWARNINGS": "ignore", "OMP_NUM_THREADS": "1"}
TINY_COLUMNS = [
    "run",
    "method",
    "line_search",
    "repeat",
    "dofs",
    "untagged_facets",
    "levels",
    "newton_iterations",
    "newton_iterations_total",
    "polish_solves",
    "polish_solves_total",
    "linear_solver",
    "krylov_iterations",
    "converged",
    "reason",
    "eta",
    "active_measure",
    "outcome",
    "seconds",
    "peak_rss_mib",
    "ranks",
    "pareto",
    "failure",
]


def _study(cwd: Path, *args: str, nproc: int = 1) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "contact.app.cli", "study", *args]
    if nproc > 1:
        cmd = [str(MPIRUN), "-n", str(nproc), *cmd]
    return subprocess.run(cmd, cwd=cwd, env=ENV, capture_output=True, text=True, timeout=300)


def _rows(folder: Path) -> tuple[list[str], list[dict]]:
    with open(folder / "study.csv", newline="") as fh:
        reader = csv.DictReader(fh)
        return list(reader.fieldnames), list(reader)


def _tiny(tmp_path_factory, nproc: int) -> tuple[subprocess.CompletedProcess, Path]:
    tmp = tmp_path_factory.mktemp(f"tiny_np{nproc}")
    out = tmp / "out"
    proc = _study(tmp, str(ROOT / "configs" / "studies" / "tiny.yaml"), "-o", str(out), nproc=nproc)
    assert proc.returncode == 0, proc.stderr + proc.stdout
    return proc, out


@pytest.fixture(scope="module")
def tiny_serial(tmp_path_factory):
    return _tiny(tmp_path_factory, 1)


def test_tiny_study_end_to_end(tiny_serial) -> None:
    proc, out = tiny_serial
    assert sorted(p.name for p in out.iterdir()) == [
        ".contact-result",
        "levels.csv",
        "speed_accuracy.png",
        "study.csv",
        "study.json",
    ]
    assert (out / "speed_accuracy.png").stat().st_size > 10_000
    assert sorted(p.name for p in out.parent.iterdir()) == ["out"]  # no .partial / .old left over
    assert not [ln for ln in proc.stderr.splitlines() if ln.strip()], proc.stderr

    columns, rows = _rows(out)
    assert columns == TINY_COLUMNS
    assert [(r["run"], r["method"], r["line_search"]) for r in rows] == [
        ("1", "fb", "basic"),
        ("2", "min", "basic"),
        ("3", "vinewtonrsls", "basic"),
    ]
    for r in rows:
        assert (
            r["converged"] == "True" and r["failure"] == "" and r["reason"].startswith("converged")
        )
        assert r["outcome"] == "converged"
        assert r["dofs"] == "289" and r["levels"] == "1" and r["ranks"] == "1"
        assert 1 <= int(r["newton_iterations"]) == int(r["newton_iterations_total"]) <= 50
        assert float(r["seconds"]) > 0 and float(r["peak_rss_mib"]) > 10
    etas = [float(r["eta"]) for r in rows]  # the same discrete solution, so the same η
    assert max(etas) - min(etas) < 1e-8 * etas[0]
    assert any(r["pareto"] == "True" for r in rows)

    saved = json.loads((out / "study.json").read_text())
    assert saved["name"] == "tiny" and saved["runs"] == 3 and saved["set"] == ["mesh.cells=[16,16]"]
    assert saved["axes"] == {"method": ["fb", "min", "vinewtonrsls"], "line_search": ["basic"]}
    assert saved["base_scene"]["mesh"]["cells"] == [16, 16]

    progress = [ln for ln in proc.stdout.splitlines() if ln.startswith("[")]
    assert len(progress) == 3
    assert progress[0].startswith("[1/3] method=fb line_search=basic → converged, ")
    assert "(ETA " in progress[0] and "(ETA " not in progress[-1]


@pytest.mark.mpi
def test_tiny_study_two_ranks_same_iterations(tiny_serial, tmp_path_factory) -> None:
    _, serial = tiny_serial
    proc, parallel = _tiny(tmp_path_factory, 2)
    # progress from rank 0 only
    assert sum(ln.startswith("[") for ln in proc.stdout.splitlines()) == 3
    _, s_rows = _rows(serial)
    _, p_rows = _rows(parallel)
    # the same counts on 2 ranks: every kink is decided with the tie tolerance (no node of
    # this scene is within round-off of it) and Newton's last steps contract by orders of
    # magnitude, far from the stopping test: the partition's rounding cannot move a count
    key = ("method", "dofs", "newton_iterations", "converged", "reason")
    assert [tuple(r[k] for k in key) for r in p_rows] == [tuple(r[k] for k in key) for r in s_rows]
    assert {r["ranks"] for r in p_rows} == {"2"}
    for s, p in zip(s_rows, p_rows):
        assert math.isclose(float(s["eta"]), float(p["eta"]), rel_tol=1e-8)


def test_failing_runs_are_rows(tmp_path: Path) -> None:
    """max_it = 1 cannot converge and u0 = 1/x is infinite at x = 0 (bad input, found
    before the solve): those runs are failure rows, the others converge, the study exits 0."""
    study = {
        "name": "failing",
        "scene": str(SQUARE),
        "set": ["mesh.cells=[8,8]"],
        "axes": {"method": ["fb", "min"], "max_it": [1, 50], "u0": ["0", "1/x"]},
    }
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    proc = _study(tmp_path, "study.yaml", "-o", "out")
    assert proc.returncode == 0, proc.stderr + proc.stdout
    columns, rows = _rows(tmp_path / "out")
    assert columns[:4] == ["run", "method", "max_it", "u0"] and columns[-1] == "failure"
    assert len(rows) == 8
    for r in rows:
        ok = r["max_it"] == "50" and r["u0"] == "0"
        assert (r["converged"] == "True") == ok, r
        assert (r["failure"] == "") == ok, r
        if r["u0"] == "1/x":
            assert r["reason"] == "" and r["outcome"] == "error"
            assert (
                r["failure"]
                == "solver.u0: not a finite number at 9 of 81 nodes, e.g. at x = 0, y = 0"
            )
        elif r["max_it"] == "1":
            assert r["reason"] == "diverged_max_it" and r["newton_iterations"] == "1"
            assert r["failure"].startswith(
                "did not converge (diverged_max_it) after 1 Newton iterations"
            )
        if not ok:
            assert r["eta"] == "" and r["pareto"] == "False"
    assert "FAILED (diverged_max_it), 1 its" in proc.stdout
    assert (tmp_path / "out" / "speed_accuracy.png").is_file()


def test_exceptions_are_rows(monkeypatch) -> None:
    """A run that raises (a ConfigError from an impossible combination or anything else)
    is a failure row; the next run still happens."""
    import contact.setup.run
    from contact.app.study import run_study
    from contact.base.errors import ConfigError

    real = contact.setup.run.solve

    def fake(scene, *args, **kw):
        method = scene.config.solver.method
        if method == "min":
            raise ConfigError("solver.method: min cannot do this")
        if method == "blend":
            raise RuntimeError("boom\nsecond line")
        return real(scene, *args, **kw)

    monkeypatch.setattr(contact.setup.run, "solve", fake)
    rows, _ = run_study(
        {
            "scene": str(SQUARE),
            "set": ["mesh.cells=[8,8]"],
            "warmup": False,
            "axes": {"method": ["min", "blend", "fb"]},
        },
        verbose=False,
    )
    assert [(r["method"], r["converged"], r["failure"]) for r in rows] == [
        ("min", False, "solver.method: min cannot do this"),
        ("blend", False, "RuntimeError: boom second line"),
        ("fb", True, ""),
    ]
    assert rows[0]["dofs"] == "" and rows[0]["seconds"] >= 0
    assert [r["outcome"] for r in rows] == ["error", "error", "converged"]


def test_adaptive_and_single_runs_with_exact_solution() -> None:
    """Problem A (exact solution known): one solve against two uniform levels; level
    refines the base mesh uniformly (4× the cells per level in 2D)."""
    from contact.app.study import run_study

    rows, levels = run_study(
        {
            "scene": str(FREE),
            "set": ["mesh.cells=[8,4]"],
            "adapt": {"max_levels": 2},
            "axes": {"strategy": ["none", "uniform"], "level": [0, 1]},
        },
        verbose=False,
    )
    by = {(r["strategy"], r["level"]): r for r in rows}
    assert all(r["converged"] and r["failure"] == "" for r in rows)
    assert by["none", 0]["levels"] == 1 and by["none", 0]["stop"] == "single solve"
    assert by["uniform", 0]["levels"] == 2 and "max_levels" in by["uniform", 0]["stop"]
    # two uniform levels from level 0 = one solve at level 1
    assert by["uniform", 0]["dofs"] == by["none", 1]["dofs"] == 153
    assert math.isclose(by["uniform", 0]["error"], by["none", 1]["error"], rel_tol=1e-6)
    assert by["uniform", 0]["newton_iterations_total"] > by["uniform", 0]["newton_iterations"]
    assert by["none", 1]["error"] < by["none", 0]["error"] < by["none", 0]["eta"] * 10
    assert all(r["eta"] > 0 for r in rows)
    # levels.csv: one row per level, the last one of a run equal to the run's row
    assert [(lv["run"], lv["level"]) for lv in levels] == [
        (1, 0),
        (2, 0),
        (3, 0),
        (3, 1),
        (4, 0),
        (4, 1),
    ]
    for r in rows:
        mine = [lv for lv in levels if lv["run"] == r["run"]]
        assert mine[-1]["dofs"] == r["dofs"] and mine[-1]["error"] == r["error"]
        assert [lv["seconds"] for lv in mine] == sorted(lv["seconds"] for lv in mine) and mine[-1][
            "seconds"
        ] <= r["seconds"]
    adaptive = [lv for lv in levels if lv["run"] == 3]
    assert adaptive[1]["dofs"] > adaptive[0]["dofs"] and adaptive[1]["error"] < adaptive[0]["error"]


def test_shipped_studies_validate() -> None:
    """Every study file `make bench` runs validates; the stability study crosses its cases
    (the stress cases (a)–(g), the friction cases (h)–(j), (k)–(o) of issue 11 and (q) of
    issue 26) with the five methods, every one a cold start; its 1024² part (k) crosses κ
    and sequencing with fb, min and blend."""
    from contact.app.study import load_study

    tiny = load_study(ROOT / "configs" / "studies" / "tiny.yaml")
    assert len(tiny.runs()) == 3 and not tiny.has_exact
    for path in sorted((ROOT / "configs" / "studies").glob("*.yaml")):
        assert load_study(path).runs(), path
    stab = load_study(ROOT / "configs" / "studies" / "stability.yaml")
    assert stab.axes["method"] == ["fb", "min", "blend", "vinewtonrsls", "vinewtonssls"]
    assert {label[:3] for label in stab.cases} == {f"({c})" for c in "abcdefghijklmnoq"}
    # plain Newton-min (no globalization) keeps rows of its own, so its cycles stay visible
    plain = {label for label, c in stab.cases.items() if c.params.get("line_search") == "basic"}
    assert plain == {
        "(d) plain Newton",
        "(k) kappa=1e4 at 128², plain Newton",
        "(q) two-body stack, plain Newton",
    }
    assert stab.cases["(q) two-body stack"].config.solver.line_search == "auto"  # the default
    assert len(stab.runs()) == 5 * len(stab.cases) and stab.charts == ["stability"]
    assert all(
        c.config.solver.sequence in ("off", False)
        for label, c in stab.cases.items()
        if not label.startswith(("(h)", "(i)", "(j)"))
    )  # friction is never sequenced
    scale = load_study(ROOT / "configs" / "studies" / "stability_scale.yaml")
    assert scale.axes["method"] == ["fb", "min", "blend"] and list(
        scale.base_config.mesh.cells
    ) == [
        1024,
        1024,
    ]
    assert scale.axes["sequence"] == ["auto", "off"] and len(scale.runs()) == 3 * 2 * len(
        scale.axes["kappa"]
    )
    assert (
        load_study(ROOT / "configs" / "studies" / "speed_accuracy_hertz.yaml").accuracy
        == "hertz_error"
    )


def test_pareto_front() -> None:
    from contact.app.study import pareto_front

    pts = [
        (1.0, 1.0),
        (2.0, 0.5),
        (3.0, 0.5),
        (0.5, 1.0 + 1e-12),
        (1.0, 2.0),
        (math.nan, 0.1),
        (4.0, 0.1),
    ]
    assert pareto_front(pts) == [False, True, False, True, False, False, True]


BAD = {
    "unknown_key": (
        "colour: unknown key (expected one of name, scene, set, axes, cases, adapt, charts, "
        "repeat, warmup)",
        {"colour": "red"},
    ),
    "unknown_axis": (
        "axes.solver: unknown axis (expected one of method, mu, c,",
        {"axes": {"solver": ["fb"]}},
    ),
    "bad_method": (
        "axes.method[1]: 'fbb' is not one of fb, min, blend, vinewtonrsls, vinewtonssls",
        {"axes": {"method": ["fb", "fbb"]}},
    ),
    "bad_c": ("axes.c[0]: must be > 0, got -1", {"axes": {"c": [-1, "auto"]}}),
    "bad_linear_solver": (
        "axes.linear_solver[0]: 'lu' is not one of direct, gamg",
        {"axes": {"linear_solver": ["lu"]}},
    ),
    "bad_u0": ("axes.u0[0]: unknown name 'foo'", {"axes": {"u0": ["foo"]}}),
    "axis_not_list": (
        "axes.method: expected a non-empty list of values, got a string 'fb'",
        {"axes": {"method": "fb"}},
    ),
    "axis_duplicate": ("axes.level[1]: 1 is listed twice", {"axes": {"level": [1, 1]}}),
    "bad_strategy": (
        "adapt.strategy: 'best' is not one of none, uniform, dorfler, maximum",
        {"adapt": {"strategy": "best"}},
    ),
    "repeat_string": ("repeat: expected an integer, got a string 'twice'", {"repeat": "twice"}),
    "missing_scene_key": ("scene: required key is missing", {"scene": None}),
    "missing_scene_file": ("scene: no such file '{tmp}/nope.yaml'", {"scene": "nope.yaml"}),
    "set_not_string": ("set[0]: expected a string KEY.PATH=VALUE, got an integer 3", {"set": [3]}),
    "set_bad_scene_key": ("scene.solver.metod: unknown key", {"set": ["solver.metod=fb"]}),
    "unknown_chart": (
        "charts: unknown chart 'pie' (expected some of speed_accuracy, stability, iterations)",
        {"charts": ["speed_accuracy", "pie"]},
    ),
    "case_not_mapping": (
        "cases.far: expected a mapping, got a string 'u0=10'",
        {"cases": {"far": "u0=10"}},
    ),
    "case_unknown_key": (
        "cases.far.colour: unknown key (expected scene, set or an axis: method,",
        {"cases": {"far": {"colour": 1}}},
    ),
    "case_is_axis": (
        "cases.far.method: is also an axis of the study; set it in one place",
        {"cases": {"far": {"method": "min"}}},
    ),
    "case_bad_value": ("cases.far.u0: unknown name 'foo'", {"cases": {"far": {"u0": "foo"}}}),
    "case_missing_scene": (
        "cases.far.scene: no such file '{tmp}/nope.yaml'",
        {"cases": {"far": {"scene": "nope.yaml"}}},
    ),
    "case_bad_set": (
        "cases.far.scene.solver.metod: unknown key",
        {"cases": {"far": {"set": ["solver.metod=fb"]}}},
    ),
    "malformed_yaml": (
        "{study}: malformed YAML (line 2, column 13): mapping values are not allowed",
        "name: x\naxes: method: [fb]\n",
    ),
}


@pytest.mark.parametrize("expect,content", list(BAD.values()), ids=list(BAD))
def test_bad_study_fails_before_running(expect: str, content, tmp_path: Path) -> None:
    tmp_path = tmp_path.resolve()
    study_file = tmp_path / "study.yaml"
    if isinstance(content, str):
        study_file.write_text(content)
    else:
        study = {
            "scene": str(SQUARE),
            "set": ["mesh.cells=[8,8]"],
            "axes": {"method": ["fb"]},
            **content,
        }
        study = {k: v for k, v in study.items() if v is not None}
        study_file.write_text(yaml.safe_dump(study, sort_keys=False))
    before = sorted(tmp_path.rglob("*"))
    proc = _study(tmp_path, str(study_file), "-o", str(tmp_path / "out"))
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2, proc.stderr + proc.stdout
    assert "Traceback" not in proc.stderr + proc.stdout and not proc.stdout.strip()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(PREFIX + expect.format(tmp=tmp_path, study=study_file)), lines[0]
    assert sorted(tmp_path.rglob("*")) == before  # no output folder, nothing else either


def test_outcome_classes() -> None:
    from contact.app.study import outcome

    assert outcome({"converged": True, "reason": "converged_fnorm_abs"}) == "converged"
    assert outcome({"converged": False, "reason": "diverged_max_it"}) == "max iterations"
    assert outcome({"converged": False, "reason": "diverged_line_search"}) == "stalled"
    assert outcome({"converged": False, "reason": "diverged_local_min"}) == "stalled"
    assert outcome({"converged": False, "reason": "diverged_function_nanorinf"}) == "diverged"
    assert outcome({"converged": False, "reason": "diverged_linear_solve"}) == "diverged"
    assert outcome({"converged": False, "reason": ""}) == "error"
    # a hyperelastic run that converged to no stable state (study rows of load paths)
    ok = {"converged": True, "reason": "converged_fnorm_abs"}
    assert outcome({**ok, "min_det_F": 0.5, "tangent_negative_eigenvalues": 0}) == "converged"
    assert outcome({**ok, "min_det_F": 0.5, "tangent_negative_eigenvalues": 2}) == "unstable"
    assert outcome({**ok, "min_det_F": -1.1, "tangent_negative_eigenvalues": 0}) == "inverted"
    assert outcome({**ok, "min_det_F": "", "tangent_negative_eigenvalues": ""}) == "converged"


def test_cases_stability_and_iterations_charts(tmp_path: Path) -> None:
    """Named cases are crossed with the axes (case first, method fastest), each row names
    its case and outcome; a case may swap the scene; the stability map and the
    iterations-per-level chart are drawn; nested iteration needs fewer Newton steps than a
    cold start on the finer levels of problem A."""
    from contact.app.study import run_study

    study = {
        "name": "cases",
        "scene": str(FREE),
        "set": ["mesh.cells=[8,4]"],
        "axes": {"method": ["fb", "min"]},
        "cases": {
            "nested": {"strategy": "uniform", "nested": True},
            "cold": {"strategy": "uniform", "nested": False},
            "one step": {"strategy": "none", "max_it": 1},
            "square": {"scene": str(SQUARE), "set": ["mesh.cells=[8,8]"], "strategy": "none"},
        },
        "adapt": {"max_levels": 3},
        "charts": ["stability", "iterations", "speed_accuracy"],
    }
    rows, levels = run_study(study, tmp_path / "out", verbose=False)
    assert [(r["case"], r["method"]) for r in rows] == [
        (c, m) for c in ("nested", "cold", "one step", "square") for m in ("fb", "min")
    ]
    outcomes = {(r["case"], r["method"]): r["outcome"] for r in rows}
    assert outcomes == {
        **{(c, m): "converged" for c in ("nested", "cold", "square") for m in ("fb", "min")},
        ("one step", "fb"): "max iterations",
        ("one step", "min"): "max iterations",
    }
    assert {r["dofs"] for r in rows if r["case"] == "square"} == {81}
    its = {(lv["case"], lv["method"], lv["level"]): lv["newton_iterations"] for lv in levels}
    for m in ("fb", "min"):
        assert its["nested", m, 0] == its["cold", m, 0]  # the same first level
        # warm start pays on level 2 (1–2 against ≥ 4)
        assert its["nested", m, 2] < its["cold", m, 2]
    for chart in ("stability", "iterations", "speed_accuracy"):
        assert (tmp_path / "out" / f"{chart}.png").stat().st_size > 10_000
    header = (tmp_path / "out" / "levels.csv").read_text().splitlines()[0].split(",")
    assert header[:4] == ["run", "case", "method", "repeat"] and "level" in header


def test_a_hyperelastic_stability_map_tells_unstable_answers(tmp_path: Path) -> None:
    """The SVK block pressed to 50 % in one step (past its material limit): plain Newton
    converges to the homogeneous state, a saddle of the energy — the row says ``unstable``
    and carries K_T's negative eigenvalues and det F > 0; the energy search (the default)
    never returns that state as a converged one: finding no stable state it takes the
    equilibrium branch and the row says ``unstable`` too (or it finds a stable state); the
    neo-Hookean block converges to a stable state."""
    from contact.app.study import run_study

    block = ROOT / "configs" / "hyperelastic_block.yaml"
    svk = ["model.law=saint_venant_kirchhoff", "constants.compression=0.5", "load.cuts=0"]
    study = {
        "name": "hyper",
        "scene": str(block),
        "set": ["constants.compression=0.5", "load.cuts=0", "output.png=false"],
        "axes": {"method": ["fb"], "steps": [1]},
        "cases": {
            "NH": {},
            "SVK plain": {"scene": str(block), "set": svk, "line_search": "basic"},
            "SVK": {"scene": str(block), "set": svk},
        },
        "adapt": {"strategy": "none"},
        "charts": ["stability"],
    }
    rows, _ = run_study(study, tmp_path / "out", verbose=False)
    by = {r["case"]: r for r in rows}
    assert by["NH"]["outcome"] == "converged" and by["NH"]["tangent_negative_eigenvalues"] == 0
    plain = by["SVK plain"]
    assert plain["outcome"] == "unstable" and plain["tangent_negative_eigenvalues"] > 0
    assert plain["min_det_F"] > 0
    assert by["SVK"]["outcome"] != "converged" or by["SVK"]["tangent_negative_eigenvalues"] == 0
    assert (tmp_path / "out" / "stability.png").stat().st_size > 10_000


def test_growth_and_indicators_reach_the_adaptive_runs(tmp_path: Path) -> None:
    """``growth`` and ``indicators`` are study axes and ``adapt`` keys like ``theta``: with
    growth 2 every level has at least twice its parent's DoFs, with growth 1 (Dörfler
    alone, θ = 0.2) some level has fewer; residual indicators keep the same loop running."""
    from contact.app.study import load_study, run_study
    from contact.base.errors import ConfigError

    study = {
        "name": "growth",
        "scene": str(FREE),
        "set": ["mesh.cells=[8,4]"],
        "axes": {"growth": [1, 2]},
        "adapt": {"strategy": "dorfler", "theta": 0.2, "max_levels": 4, "indicators": "residual"},
    }
    rows, levels = run_study(study, tmp_path / "out", verbose=False)
    assert [r["growth"] for r in rows] == [1, 2]
    assert all(r["outcome"] == "converged" for r in rows)
    dofs = {g: [lv["dofs"] for lv in levels if lv["growth"] == g] for g in (1, 2)}
    assert len(dofs[2]) == 4
    assert all(b >= 2 * a * 0.9 for a, b in zip(dofs[2], dofs[2][1:]))  # cells ×2 ≈ DoFs ×2
    assert any(b < 1.5 * a for a, b in zip(dofs[1], dofs[1][1:]))
    with pytest.raises(ConfigError, match=r"adapt\.indicators"):
        load_study({**study, "adapt": {"indicators": "gradient"}})
