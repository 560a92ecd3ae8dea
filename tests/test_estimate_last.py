"""``adapt.estimate_last: false``: a loop run on a level budget ends with its last solution.

A level the loop knows to be its last before estimating it (``max_levels`` reached, or for
P1 triangles a next level certainly above ``max_dofs``) is solved and not estimated: the
levels are those of the loop with its last estimate, the last one has no η, η_T or
effectivity, and every output says so (convergence.csv and summary.json empty / null, no
η_T in its step of the field files, no η point in the convergence chart) — through
``contact.adapt`` of a scene, the hp loop and ``contact run`` serially and on 2 and 3
ranks.  A level not known to be the last (a tolerance met) is still estimated, and the
option is refused where every solve needs its estimate (adaptive stopping)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import contact
from contact.base.errors import ConfigError

import pytest
from clirun import ROOT
from clirun import contact as cli
from readback import read_vtu, read_xdmf
from scene_runs import TIMEOUT, read_folder, same_run

EX9 = ROOT / "configs" / "peers" / "petsc_ex9.yaml"
LSHAPE = ROOT / "configs" / "lshape_corner.yaml"
SMOOTH = ROOT / "configs" / "signorini_smooth.yaml"


def _scene(path: Path, *sets: str) -> contact.Scene:
    return contact.load_scene(path, ["output.verbose=false", *sets])


def _same_levels(budget, full) -> None:
    """The loop without its last estimate solved the levels of the loop with it: the same
    DoFs and errors, the same η on every level but the last, which has none."""
    assert [r["dofs"] for r in budget.rows] == [r["dofs"] for r in full.rows]
    assert [r["error"] for r in budget.rows] == pytest.approx([r["error"] for r in full.rows])
    assert [r["eta"] for r in budget.rows[:-1]] == pytest.approx([r["eta"] for r in full.rows[:-1]])
    last = budget.levels[-1]
    assert not last.estimate.computed and last.estimate.eta_T is None
    assert budget.rows[-1]["eta"] == budget.rows[-1]["effectivity"] == ""
    assert last.seconds["estimate"] == 0.0
    assert full.levels[-1].estimate.computed and full.rows[-1]["eta"] > 0


@pytest.mark.parametrize("indicators", ["estimator", "residual"])
def test_a_level_budget_is_known_before_the_last_estimate(indicators: str) -> None:
    """ex9, P1, growth 3: with ``max_levels`` and with ``max_dofs`` (the next level
    certainly above it: at least 1.5 new vertices per marked triangle) the last level is
    solved, not estimated; with the residual indicators marking, no bound is computed on it
    either (the loop with its last estimate computes the bound there)."""
    scene = _scene(EX9)
    opts = {"growth": 3, "indicators": indicators, "max_levels": 4}
    full = contact.adapt(scene, **opts)
    budget = contact.adapt(scene, **opts, estimate_last=False)
    assert budget.stop == full.stop == "reached max_levels = 4"
    _same_levels(budget, full)
    if indicators == "residual":  # the loop with its last estimate bounds its last level
        assert full.rows[-1]["estimator"] == "equilibrated"
        assert "estimator" not in budget.rows[-1]
        assert {r["estimator"] for r in budget.rows[:-1]} == {"residual"}
    opts.update(max_levels=20, max_dofs=20_000)
    full = contact.adapt(scene, **opts)
    budget = contact.adapt(scene, **opts, estimate_last=False)
    assert budget.stop.startswith("the next level would have at least")
    assert budget.stop.endswith("DoFs > max_dofs = 20000") and full.stop.endswith("= 20000")
    _same_levels(budget, full)


def test_a_level_not_known_to_be_the_last_is_estimated() -> None:
    """A loop stopped by its tolerance learns that its level is the last from the level's
    estimate: it is estimated (η ≤ tol, the guaranteed bound ≥ the error) with or without
    ``estimate_last``; and P2 levels, whose next level's DoFs the loop bounds only after
    marking, are all estimated."""
    scene = _scene(EX9)
    opts = {"growth": 2, "indicators": "residual", "tol": 0.02, "max_levels": 20}
    full = contact.adapt(scene, **opts)
    budget = contact.adapt(scene, **opts, estimate_last=False)
    assert budget.stop == full.stop and budget.stop.startswith("eta = ")
    assert [r["eta"] for r in budget.rows] == pytest.approx([r["eta"] for r in full.rows])
    assert [r["estimator"] for r in budget.rows] == [r["estimator"] for r in full.rows]
    last = budget.rows[-1]
    assert last["estimator"] == "equilibrated" and last["error"] <= last["eta"] <= 0.02
    p2 = _scene(EX9, "mesh.degree=2", "mesh.cells=[8,8]")
    run = contact.adapt(p2, growth=2, max_dofs=6000, max_levels=20, estimate_last=False)
    assert run.stop.startswith("the next level would have") and len(run.levels) > 1
    assert all(lv.estimate.computed for lv in run.levels)


def test_the_hp_loop_ends_with_its_last_solution() -> None:
    """``strategy: hp``: the level ``max_levels`` is solved and not estimated; the levels
    (unknowns, degrees, errors) are those of the loop with its last estimate."""
    scene = _scene(SMOOTH)
    opts = {"strategy": "hp", "p_max": 3, "max_levels": 3}
    full = contact.adapt(scene, **opts)
    budget = contact.adapt(scene, **opts, estimate_last=False)
    assert budget.stop == full.stop == "reached max_levels = 3"
    _same_levels(budget, full)
    assert [r["p_max"] for r in budget.rows] == [r["p_max"] for r in full.rows]


def test_refused_with_adaptive_stopping(tmp_path: Path) -> None:
    """Adaptive stopping balances every solve against its level's estimate: the option is
    refused when the scene is loaded, through the API and by ``contact run`` (exit 2, one
    line naming the key)."""
    sets = ["solver.stopping=adaptive", "adapt.estimate_last=false"]
    with pytest.raises(ConfigError, match=r"^adapt\.estimate_last: false does not go with"):
        _scene(EX9, *sets)
    with pytest.raises(ConfigError, match=r"^adapt\.estimate_last: false does not go with"):
        contact.adapt(_scene(EX9, "solver.stopping=adaptive"), estimate_last=False)
    args = [arg for s in sets for arg in ("--set", s)]
    proc = cli(tmp_path, "run", str(EX9), "-o", str(tmp_path / "out"), *args)
    assert proc.returncode == 2 and not (tmp_path / "out").exists()
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith("contact: error: adapt.estimate_last: false does not go with"), line


def _run(tmp: Path, ranks: int) -> Path:
    """``contact run`` of the L-shape with 3 levels, the last not estimated, its default
    outputs (every level's fields, the pictures); its folder."""
    out = tmp / f"np{ranks}"
    sets = ["adapt.max_levels=3", "adapt.estimate_last=false"]
    args = [arg for s in sets for arg in ("--set", s)]
    proc = cli(tmp, "run", str(LSHAPE), "-o", str(out), *args, ranks=ranks, timeout=TIMEOUT[ranks])
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and "warning" not in proc.stderr.lower(), proc.stderr
    return out


@pytest.fixture(scope="module")
def serial(tmp_path_factory) -> Path:
    return _run(tmp_path_factory.mktemp("serial"), 0)


def test_the_cli_writes_a_level_budget_run(serial: Path) -> None:
    """Every file of the folder read back: the last level's row has no η or effectivity,
    summary.json's η is null (the earlier levels' η listed), the last step of solution.xdmf
    and solution_002.vtu have the fields of the others but η_T, and the convergence chart
    is drawn."""
    read_folder(serial)
    rows = list(csv.DictReader(open(serial / "convergence.csv")))
    assert len(rows) == 3 and rows[-1]["eta"] == rows[-1]["effectivity"] == ""
    assert all(float(r["eta"]) > float(r["error"]) > 0 for r in rows[:-1])
    assert float(rows[-1]["error"]) > 0 and float(rows[-1]["seconds_estimate"]) == 0
    summary = json.loads((serial / "summary.json").read_text())
    assert summary["eta"] is None and summary["stop"] == "reached max_levels = 3"
    assert summary["eta_per_level"][:-1] == pytest.approx([float(r["eta"]) for r in rows[:-1]])
    assert summary["eta_per_level"][-1] is None
    steps = read_xdmf(serial / "solution.xdmf")
    assert [("eta_T" in s["cell"]) for s in steps] == [True, True, False]
    assert set(steps[-1]["point"]) == set(steps[0]["point"])
    for k, estimated in enumerate((True, True, False)):
        grid = read_vtu(serial / f"solution_{k:03d}.vtu")
        assert ("eta_T" in grid.cell_data) == estimated, k
    assert set(summary["pictures"].values()) == {"written"}
    assert "convergence.png" in summary["pictures"]


@pytest.mark.mpi
@pytest.mark.parametrize("ranks", [2, 3])
def test_the_cli_level_budget_run_under_mpirun_matches_serial(
    tmp_path: Path, serial: Path, ranks: int
) -> None:
    """The same folder on 2 and 3 ranks: the same files, summary.json's answer (η null on
    the last level) and contact table as the serial run."""
    out = _run(tmp_path, ranks)
    same_run(serial, out, ranks)
    assert json.loads((out / "summary.json").read_text())["eta_per_level"][-1] is None


def test_a_load_path_and_a_study_on_a_level_budget(tmp_path: Path) -> None:
    """The loop at every step of a load path and the loop of a study's adaptive run: their
    last levels have no η (steps.csv, convergence.csv, levels.csv, study.csv), and the load
    path's field steps, each a step's last level, no η_T."""
    out = tmp_path / "path"
    sets = [
        "mesh.cells=[20,6]",
        "load.steps=2",
        "load.adapt=each",
        "adapt.strategy=dorfler",
        "adapt.max_levels=2",
        "adapt.estimate_last=false",
    ]
    scene = str(ROOT / "configs" / "friction_block_2d.yaml")
    proc = cli(
        tmp_path, "run", scene, "-o", str(out), "-q", *(a for s in sets for a in ("--set", s))
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    read_folder(out)
    steps = list(csv.DictReader(open(out / "steps.csv")))
    assert len(steps) == 2 and all(r["eta"] == "" and r["converged"] == "True" for r in steps)
    levels = list(csv.DictReader(open(out / "convergence.csv")))
    assert [(r["level"], r["eta"] != "") for r in levels] == [("0", True), ("1", False)] * 2
    assert not any("eta_T" in s["cell"] for s in read_xdmf(out / "solution.xdmf"))
    study = tmp_path / "study.yaml"
    study.write_text(
        f"name: budget\nscene: {LSHAPE}\naxes: {{method: [fb]}}\n"
        "adapt: {strategy: dorfler, max_levels: 3, estimate_last: false}\n"
    )
    proc = cli(tmp_path, "study", str(study), "-o", str(tmp_path / "s"), "-q")
    assert proc.returncode == 0, proc.stderr[-2000:]
    levels = list(csv.DictReader(open(tmp_path / "s" / "levels.csv")))
    assert [r["eta"] != "" for r in levels] == [True, True, False]
    (run,) = csv.DictReader(open(tmp_path / "s" / "study.csv"))
    assert run["eta"] == "" and float(run["error"]) > 0 and run["levels"] == "3"
