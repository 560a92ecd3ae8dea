"""Quasi-static load paths (issue 12): the pseudo-time t in expressions, 1 step = 10 steps of a
proportional stick-only loading, slip accumulating over the steps of a pulled block, warm
starts, and the per-step output folder of `contact run`."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import contact
from contact.base import expressions
from contact.setup.run import load_times, run_load_path

import numpy as np
import pytest
from test_friction import BLOCK, block, coulomb

ROOT = Path(__file__).resolve().parents[1]


def test_pseudo_time_in_expressions():
    f = expressions.to_numpy("0.01*t + x", t=0.5)
    assert np.allclose(f(np.array([[1.0, 2.0], [0, 0], [0, 0]])), [1.005, 2.005])
    assert expressions.uses_time("2*t") and not expressions.uses_time("x")
    assert not expressions.is_constant("2*t") and expressions.is_constant("2")
    assert load_times(block("load.steps=4").config) == [0.25, 0.5, 0.75, 1.0]
    assert load_times(block("load.times=[0.1, 0.5, 2]").config) == [0.1, 0.5, 2.0]
    assert load_times(block().config) == [1.0]


@pytest.mark.parametrize("predictor", ["none", "secant"])
def test_proportional_stick_loading_does_not_depend_on_the_steps(predictor):
    """F = 1 and a small drag: every node sticks at every step, the problem is linear in t,
    and 10 steps end where 1 step does (warm starts: 1 Newton step after the first; with
    the secant predictor none from the third step on: it is exact on a linear path)."""
    sets = [*coulomb(1.0), 'data.u_D=["0.002*t", "-0.01*t"]']
    one = run_load_path(block(*sets))
    ten = run_load_path(block(*sets, "load.steps=10", f"load.predictor={predictor}"), keep_all=True)
    assert one.converged and ten.converged and len(ten.steps) == 10
    for step in ten.steps:
        f = step.result.friction
        assert np.all(f["status"] == 1)
        # far from both kinks (|λ_t| ≤ 0.56 F|λ_n|, every |λ_n| ≥ 0.42 max|λ_n|): the law is
        # linear around every iterate, so a warm-started step is one exact linear solve
        # (its ‖Φ‖ ~ 1e-17, 100× below the stopping test): a count rounding cannot move
        assert np.all(np.linalg.norm(f["lambda_t"], axis=1) <= 0.9 * np.abs(f["lambda_n"]))
        assert np.all(np.abs(f["lambda_n"]) >= 0.1 * np.max(np.abs(f["lambda_n"])))
    its = [s.result.iterations for s in ten.steps]
    if predictor == "none":
        assert its[1:] == [1] * 9
        assert all(s.result.predictor is None for s in ten.steps)
    else:  # the predictor's ‖Φ‖ is round-off (~1e-17, 100× below the stopping test)
        assert its[1:] == [1] + [0] * 8
        assert [s.result.predictor for s in ten.steps] == [None, None] + [True] * 8
    u1, u10 = one.steps[-1].result.u_h.x.array, ten.steps[-1].result.u_h.x.array
    assert np.max(np.abs(u1 - u10)) <= 1e-8 * np.max(np.abs(u1))


def test_pulled_block_slip_accumulates_over_the_steps():
    """Pressed, then dragged by 0.05: stick → partial slip → full sliding.  After the first
    step (which also presses the block, so the front edge slides outward) slip increments
    point along the drag, add up to the one-step slip, and once sliding each step slips by the
    drag increment (the block translates rigidly at the bottom); Coulomb's force law holds."""
    sets = [*coulomb(0.3), 'data.u_D=["0.05*t", "-0.01"]']
    path = run_load_path(block(*sets, "load.steps=10"), keep_all=True)
    one = run_load_path(block(*sets)).steps[-1].result
    assert path.converged
    slips = np.array([s.result.friction["slip"][:, 0] for s in path.steps])
    assert np.all(slips[1:] >= -1e-12) and slips[1:].sum() > 0.03  # along the drag
    assert np.all(slips[0, -2:] < 0)  # step 1 also presses: the front edge expands outward
    counts = [np.bincount(s.result.friction["status"], minlength=3) for s in path.steps]
    # sticks first, slides at the end
    assert counts[0][1] > 0 and counts[-1][1] == 0
    assert np.allclose(slips.sum(axis=0), one.friction["slip"][:, 0], atol=1e-12)
    assert np.allclose(slips[-1], 0.005, rtol=1e-8)
    assert max(s.result.iterations for s in path.steps) <= 10  # a bound (warm starts take 1–8)
    f = path.steps[-1].result.friction
    assert abs(
        np.sum(f["w"] * f["lambda_t"][:, 0]) - 0.3 * np.sum(f["w"] * f["lambda_n"])
    ) <= 1e-8 * abs(np.sum(f["w"] * f["lambda_n"]))


def test_run_writes_every_step(tmp_path):
    """`contact run` of a 3-step Coulomb drag: the VTK series solution.pvd over the steps (read
    back with pyvista: λ_t, slip, status, bound per step), a contact CSV per step, steps.csv with
    the resultants (contact force = −reaction, tangential = F × normal when sliding),
    summary.json with the steps, contact.csv, pressure.png and traction.png."""
    import pyvista
    import yaml

    scene = {
        **BLOCK,
        "data": {"u_D": ["0.05*t", "-0.01"]},
        "friction": {"law": "coulomb", "coefficient": 0.3},
        "load": {"steps": 3},
        "output": {"verbose": False},
    }
    path = tmp_path / "drag.yaml"
    path.write_text(yaml.safe_dump(scene))
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "contact.app.cli", "run", str(path), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    names = {p.name for p in out.iterdir()}
    assert {
        "steps.csv",
        "summary.json",
        "contact.csv",
        "pressure.png",
        "traction.png",
        "solution.png",
        "history.csv",
        "solution.pvd",
    } <= names
    assert {f"solution_00{k}.vtu" for k in (0, 1, 2)} | {
        f"contact_step_00{k}.csv" for k in (0, 1, 2)
    } <= names
    reader = pyvista.get_reader(str(out / "solution.pvd"))
    assert reader.time_values == pytest.approx([1 / 3, 2 / 3, 1.0])
    reader.set_active_time_value(reader.time_values[-1])
    grid = reader.read()[0]
    assert {"u_h", "lambda_h", "lambda_t", "slip", "status", "bound"} <= set(grid.point_data.keys())
    # off Γ_C, separated, slip
    assert set(np.unique(grid.point_data["status"])) <= {-1.0, 0.0, 2.0}
    steps = list(csv.DictReader(open(out / "steps.csv")))
    assert [float(s["time"]) for s in steps] == pytest.approx([1 / 3, 2 / 3, 1.0])
    # history.csv: every step's Newton rows under its load_step, each starting at iteration
    # 0 (the Newton rows' own `step`, the step length, had overwritten the load step's index)
    history = list(csv.DictReader(open(out / "history.csv")))
    starts = [int(h["load_step"]) for h in history if h["iteration"] == "0"]
    assert starts == [int(s["step"]) for s in steps] and len(set(starts)) == 3
    assert [int(h["load_step"]) for h in history] == sorted(int(h["load_step"]) for h in history)
    for s in steps:
        for ax in "xy":
            assert float(s[f"contact_force_{ax}"]) == pytest.approx(
                -float(s[f"reaction_force_{ax}"]), abs=1e-12
            )
    last = steps[-1]
    assert (
        float(last["friction_ratio"]) == pytest.approx(0.3, rel=1e-8)
        and int(last["stick_nodes"]) == 0
    )
    rows = list(csv.DictReader(open(out / "contact.csv")))
    assert len(rows) == 41 and {r["status"] for r in rows} <= {"slip", "separated"}
    s_ = [float(r["s"]) for r in rows]
    assert s_ == sorted(s_) and s_[0] == pytest.approx(0.0) and s_[-1] == pytest.approx(2.0)
    assert {"lambda_t", "slip", "bound", "lambda_t_norm", "slip_norm", "weight"} <= set(rows[0])
    summary = json.loads((out / "summary.json").read_text())
    assert (
        summary["steps_total"] == 3
        and len(summary["steps"]) == 3
        and summary["friction"] == "coulomb"
    )
    assert summary["newton_iterations_max_per_step"] <= 10 and "solution.pvd" in summary["files"]


MPIRUN = Path(sys.executable).parent / "mpirun"


@pytest.mark.parametrize(
    "scene,sets",
    [
        ("friction_block_2d.yaml", ["mesh.cells=[40,10]"]),
        # its mesh: plain steps 2-cycle at t = 0.3, the guard (collective) catches it on 2 ranks
        ("friction_block_2d.yaml", ["friction.form=projection"]),
        ("friction_cylinder_2d.yaml", ["mesh.cells=[64,16]", "load.steps=4"]),
        ("friction_box_3d.yaml", ["mesh.cells=[6,6,3]", "load.steps=4"]),
    ],
)
def test_serial_and_two_ranks_agree(tmp_path, scene, sets):
    """The whole load path (stick, partial slip, sliding) on 1 and 2 MPI ranks: the same
    displacements, tractions, slips (to 1e-8) and statuses (away from ties)."""
    import os

    script, path = ROOT / "tests" / "friction_run.py", str(ROOT / "configs" / scene)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    args = [f"--set={s}" for s in sets]
    s, p = tmp_path / "s.npz", tmp_path / "p.npz"
    subprocess.run(
        [sys.executable, str(script), str(s), path, *args], check=True, timeout=300, env=env
    )
    subprocess.run(
        [str(MPIRUN), "-n", "2", sys.executable, str(script), str(p), path, *args],
        check=True,
        timeout=300,
        env=env,
    )
    s, p = dict(np.load(s)), dict(np.load(p))
    assert s["converged"].all() and p["converged"].all()
    assert np.allclose(s["X"], p["X"], atol=1e-12)
    assert np.max(np.abs(s["u"] - p["u"])) <= 1e-8 * np.max(np.abs(s["u"]))
    cols = list(s["columns"])
    for name in [c for c in cols if c.startswith(("lambda", "slip", "gap"))]:
        a, b = s["surface"][:, cols.index(name)], p["surface"][:, cols.index(name)]
        # gaps are 0 in contact
        scale = np.max(np.abs(s["u"])) if name == "gap" else np.max(np.abs(a))
        assert np.max(np.abs(a - b)) <= 1e-8 * scale, name
    # the statuses agree wherever a node is clear of both kinks (rounding may tip one that
    # is on a kink: λ_n ≈ 0 with gap ≈ 0, or |λ_t| ≈ ρ with slip ≈ 0)
    col = {name: s["surface"][:, cols.index(name)] for name in cols}
    clear = (np.abs(col["lambda_n"]) > 1e-6 * np.max(np.abs(col["lambda_n"]))) | (
        col["gap"] > 1e-6 * np.max(np.abs(s["u"]))
    )
    clear &= (
        (col["bound"] - col["lambda_t_norm"] > 1e-6 * np.max(col["bound"]))
        | (col["slip_norm"] > 1e-6 * max(np.max(col["slip_norm"]), 1e-300))
        | (col["bound"] == 0)
    )
    assert clear.sum() >= 0.9 * len(clear)
    assert np.array_equal(s["status"][clear], p["status"][clear])
    # a bound (round-off may change a count); a guarded step of the projection form takes
    # its plain steps first, then backtracks (11 at t = 0.3 of the block on 1 and 2 ranks)
    bound = 20 if "friction.form=projection" in sets else 10
    assert s["its"].max() <= bound and p["its"].max() <= bound


def test_study_sweeps_friction_axes_and_steps():
    """`contact study` axes for friction: the tangential form, F, the Coulomb solver and the
    number of load steps; a load path is one row with its total and per-step Newton iterations,
    the friction ratio and the stick measure (one level row per step)."""
    from contact.app.study import load_study, run_study

    study = {
        "name": "friction",
        "scene": str(ROOT / "configs" / "friction_block_2d.yaml"),
        "set": ["mesh.cells=[20,6]"],
        "warmup": False,
        "axes": {"steps": [1, 5], "coefficient": [0.3]},
        "cases": {
            "hsw": {"friction_form": "hsw"},
            "projection": {"friction_form": "projection"},
            "fixed point": {"coulomb": "fixed_point"},
            "frictionless": {"friction": "none"},
        },
    }
    assert len(load_study(study).runs()) == 4 * 2
    rows, levels = run_study(study, verbose=False)
    assert all(r["converged"] for r in rows)
    for r in rows:
        assert r["levels"] == r["steps"]
        # (all inner solves)
        assert r["max_step_iterations"] <= (40 if r["case"] == "fixed point" else 10)
        assert r["newton_iterations_total"] == sum(
            lv["newton_iterations"] for lv in levels if lv["run"] == r["run"]
        )
        if r["case"] != "frictionless":
            assert r["friction_ratio"] == pytest.approx(0.3, rel=1e-8)  # sliding at t = 1
        else:
            assert "friction_ratio" not in r or r["friction_ratio"] == ""
    assert {r["fixed_point_iterations"] for r in rows if r["case"] == "fixed point"} != {""}


@pytest.mark.parametrize("mode", ["each", "end"])
def test_adaptive_loop_each_step_or_at_the_end(mode):
    """load.adapt: `each` refines at every step and continues on the previous step's final mesh
    (u_prev prolonged with it); `end` solves the first steps on the scene's mesh and refines at
    the last.  Either way the block ends sliding (Coulomb's force law on the refined mesh)."""
    sets = [
        *coulomb(0.3),
        'data.u_D=["0.05*t", "-0.01"]',
        "mesh.cells=[20,6]",
        "load.steps=2",
        f"load.adapt={mode}",
        "adapt.max_levels=3",
        "adapt.strategy=dorfler",
    ]
    path = run_load_path(block(*sets))
    assert path.converged and len(path.steps) == 2
    first, last = path.steps
    base = block(*sets)
    n_base = contact.solve(base).dofs
    if mode == "each":
        assert len(first.levels) == 3 and first.result.dofs > n_base
        assert (
            last.levels[0].result.dofs == first.result.dofs and last.result.dofs > first.result.dofs
        )
    else:
        assert first.levels == [] and first.result.dofs == n_base
        assert len(last.levels) == 3 and last.result.dofs > n_base
    assert "u_prev" in last.scene.history
    f = last.result.friction
    assert abs(
        np.sum(f["w"] * f["lambda_t"][:, 0]) - 0.3 * np.sum(f["w"] * f["lambda_n"])
    ) <= 1e-8 * abs(np.sum(f["w"] * f["lambda_n"]))


def test_run_keeps_the_steps_before_a_failing_one(tmp_path):
    """A step that does not converge (data that blow up at t = 1): exit 1, one line, and the
    folder holds the converged first step with converged false and failed_step 2."""
    out = tmp_path / "out"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "contact.app.cli",
            "run",
            str(ROOT / "configs" / "friction_block_2d.yaml"),
            "-o",
            str(out),
            "-q",
            "--set",
            'data.u_D=["0", "-0.01*t*(1 if t < 0.6 else 1e200)"]',
            "--set",
            "load.times=[0.5, 1.0]",
            "--set",
            "load.steps=null",
            "--set",
            "mesh.cells=[20,6]",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 1
    assert (
        proc.stderr.count("\n") == 1
        and "step 2 (t = 1) did not converge" in proc.stderr
        and "kept step 1" in proc.stderr
    )
    summary = json.loads((out / "summary.json").read_text())
    assert (
        summary["converged"] is False
        and summary["failed_step"] == 2
        and summary["steps_total"] == 1
    )
    assert (out / "solution_000.vtu").is_file() and not (out / "solution_001.vtu").exists()


def test_data_checked_at_every_step():
    """Data that depend on t are checked at each step's t: a one-line error naming the step."""
    with pytest.raises(
        contact.ConfigError, match=r"data.u_D\[0\] \(at t = 0.25\): not a finite number"
    ):
        run_load_path(block('data.u_D=["log(t - 0.35)", "-0.01"]', "load.steps=4"))


def _pushed_through(cuts: int) -> contact.Scene:
    """configs/hyperelastic_block.yaml with its plate pushed through twice the block's
    height in one step: no deformation reaches t = 1 (at t = 0.5 the quarter is flat), so
    step cutting creeps towards t = 0.5, every cut halving the step again."""
    scene = ROOT / "configs" / "hyperelastic_block.yaml"
    sets = ["constants.compression=2", "load.steps=1", f"load.cuts={cuts}"]
    return contact.load_scene(scene, [*sets, "output.verbose=false"])


def test_load_cuts_are_bounded(tmp_path):
    """``load.cuts`` beyond MAX_STEP_CUTS (20) is bad input naming the key (a million cuts
    crept towards t = 0.5 for more than 300 s); at the bound the pushed-through block ends
    with exit 1 and one line naming the step that could not be cut further."""
    from contact.setup.config import MAX_STEP_CUTS

    from clirun import contact as cli

    assert MAX_STEP_CUTS == 20
    scene = str(ROOT / "configs" / "hyperelastic_block.yaml")
    sets = ["constants.compression=2", "load.steps=1", "output.png=false"]
    args = [a for item in sets for a in ("--set", item)]
    bad = cli(tmp_path, "run", scene, "-o", "bad", "-q", *args, "--set", "load.cuts=1000000")
    lines = [ln for ln in bad.stderr.splitlines() if ln.strip()]
    assert bad.returncode == 2 and len(lines) == 1, bad.stderr
    assert (
        lines[0]
        == "contact: error: load.cuts: must be at most 20 (a step halved 20 times), got 1000000"
    )
    proc = cli(
        tmp_path, "run", scene, "-o", "out", "-q", *args, "--set", "load.cuts=20", timeout=280
    )
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 1 and len(lines) == 1 and len(lines[0]) <= 300, proc.stderr
    assert lines[0].startswith("contact: error: step 20 (t = 0.5) did not converge (")
    assert "cut 20 time(s) in a row (load.cuts: 20)" in lines[0]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["failed_step"] == 20 and len(summary["step_cuts"]) == 20


def test_no_cut_below_the_smallest_step(monkeypatch):
    """A cut that would make a step shorter than MIN_STEP × the last t stops the path
    instead: here MIN_STEP = 0.01 so that the pushed-through block stops after a few cuts
    (0.25, 0.375, …, 0.484375: the next cut would be a step of 0.0078), naming the step."""
    from contact.drivers import load_path

    assert load_path.MIN_STEP == 1e-9
    monkeypatch.setattr(load_path, "MIN_STEP", 0.01)
    path = run_load_path(_pushed_through(20))
    assert not path.converged
    assert [s.time for s in path.steps[:-1]] == [0.25, 0.375, 0.4375, 0.46875, 0.484375]
    assert (
        path.stop.startswith("step 6 (t = 0.5) did not converge (")
        and "a cut would make the step 0.00781, below the smallest (0.01 of t = 1)" in path.stop
    )
    assert len(path.cuts) == 6  # 1 → 0.5, then 0.5 → 0.25 … → 0.484375
