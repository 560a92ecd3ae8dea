"""demos/bench/bench_time_to_accuracy.py at equal certification (``--uniform-bound``): the
uniform meshes bounded as the adaptive loop certifies, driven by that bound, and the
adaptive / uniform CPU ratios at the η both certify.  Small meshes of PETSc's ex9 (its exact
solution known); the figures are the bench's."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EX9 = ROOT / "configs" / "peers" / "petsc_ex9.yaml"


@pytest.fixture(scope="module")
def bench():
    """The bench script imported as a module."""
    from bench_scripts import load

    return load("bench_time_to_accuracy")


def test_uniform_bound_refines_until_the_bound_meets_the_target(bench) -> None:
    """Every uniform mesh's bound is ≥ its energy error; the bound-driven meshes end at the
    first with η ≤ target, finer than the exact stop's (whose η is above it); without the
    flag the meshes, DoFs and errors are those of the exact sequence alone."""
    target = 5e-2
    plain = bench.uniform(EX9, target, 30_000, [], echo=False)
    rows = bench.uniform(EX9, target, 30_000, [], echo=False, bound=True)
    assert all("eta" not in r for r in plain) and plain[-1]["error"] <= target
    assert all(r["eta"] >= r["error"] for r in rows)  # guaranteed
    assert all(r["bound_cpu"] > 0 and r["estimator"] == "equilibrated" for r in rows)
    by_level = {r["level"]: r for r in rows}
    for r in plain:  # the exact sequence unchanged
        assert by_level[r["level"]]["dofs"] == r["dofs"]
        assert by_level[r["level"]]["error"] == pytest.approx(r["error"], rel=1e-9)
    path = [r for r in rows if r["certified"]]
    assert path[-1]["eta"] <= target < min(r["eta"] for r in path[:-1])
    assert by_level[plain[-1]["level"]]["eta"] > target  # the exact stop does not certify
    assert path[-1]["level"] > plain[-1]["level"]
    assert [r["level"] for r in rows] == sorted(by_level)


def test_certified_variant_stops_where_the_loop_certifies(bench) -> None:
    """A variant with its own ``adapt.tol`` runs past the level reaching the target error
    and stops on its first bound ≤ tol (residual indicators marking, the bound where it may
    meet tol), each row with the η of its estimator."""
    sets = ["adapt.growth=3", "adapt.indicators=residual", "adapt.tol=3e-2"]
    rows = bench.adaptive(EX9, 5e-2, 60_000, sets, echo=False, bound=True)
    first = next(k for k, r in enumerate(rows) if r["error"] <= 5e-2)
    assert first < len(rows) - 1  # not stopped on the error
    last = rows[-1]
    assert last["estimator"] == "equilibrated" and last["error"] <= last["eta"] <= 3e-2
    assert all(r["eta"] > 3e-2 for r in rows[:-1])
    assert rows[0]["estimator"] == "equilibrated"  # the first level learns the ratio
    assert {r["estimator"] for r in rows[1:-1]} == {"residual"}


def test_budget_stop_counts_no_estimate_of_the_last_level(bench) -> None:
    """Each level's seconds to its solution (``solved_cpu``: a loop stopping there on a level
    budget) leave out its estimate and the bound charged to the level reaching the target,
    and come after the level before it was estimated; the budget ratios divide them by the
    uniform run's seconds (which estimate nothing)."""
    sets = ["adapt.growth=3", "adapt.indicators=residual"]
    rows = bench.adaptive(EX9, 5e-2, 60_000, sets, echo=False)
    last = rows[-1]
    assert last["error"] <= 5e-2 and last["bound_cpu"] > 0  # the bound charged to it
    assert all(0 < r["solved_cpu"] <= r["cpu"] - r["bound_cpu"] for r in rows)
    assert last["solved_cpu"] < last["cpu"] - last["bound_cpu"]  # its residual estimate
    assert all(a["cpu"] < b["solved_cpu"] for a, b in zip(rows, rows[1:]))
    assert all(0 < r["solved_seconds"] < r["seconds"] for r in rows)
    uni = [dict(error=0.08, seconds=1.0, cpu=1.0), dict(error=0.04, seconds=3.0, cpu=3.0)]
    ratio = bench.ratios("ex9", "res3", 5e-2, uni, rows)
    assert ratio["budget_first_reaching_cpu"] == round(last["solved_cpu"] / 3.0, 3)
    assert ratio["first_reaching_cpu"] == round(last["cpu"] / 3.0, 3)
    assert ratio["budget_first_reaching_cpu"] < ratio["first_reaching_cpu"]


def test_a_level_budget_variant_runs_as_the_user_does(bench) -> None:
    """A variant with its own ``adapt.max_levels`` and ``adapt.estimate_last=false``: the
    loop stops on its level budget, its last level (the one reaching the target) is not
    estimated and nothing is charged to it — its seconds are its seconds to the solution —
    and the ``contact.adapt`` call's clock covers every level; the levels are those of the
    loop with its last estimate.  At equal certification it has no bounded level."""
    sets = ["adapt.growth=3", "adapt.indicators=residual"]
    full = bench.adaptive(EX9, 5e-2, 60_000, sets, echo=False)
    budget = [*sets, f"adapt.max_levels={len(full)}", "adapt.estimate_last=false"]
    rows = bench.adaptive(EX9, 5e-2, 60_000, budget, echo=False, bound=True)
    assert [r["dofs"] for r in rows] == [r["dofs"] for r in full]
    last = rows[-1]
    assert last["estimator"] == "none" and last["eta"] is None and last["bound_cpu"] == 0
    assert last["seconds"] - last["solved_seconds"] < 0.1 * last["seconds"]
    assert full[-1]["bound_cpu"] > 0 and "estimator" not in full[-1]
    assert last["call_seconds"] >= last["seconds"] and last["call_cpu"] >= last["cpu"]
    assert all("call_seconds" not in r for r in rows[:-1])
    assert bench.certified(5e-2, [_uniform_row(1, 289, 0.3, 1.0, True)] * 2, rows) == {}


def _uniform_row(level: int, dofs: int, eta: float, cpu: float, path: bool) -> dict:
    """A uniform mesh's row: its error 1/1.1 of its bound, the bound half its solve's CPU."""
    row = dict(level=level, dofs=dofs, error=eta / 1.1, eta=eta, cpu=cpu, bound_cpu=cpu / 2)
    return row | {"certified": path}


def test_certified_ratios_at_the_eta_both_certify(bench) -> None:
    """The adaptive CPU to its first bound ≤ target over the uniform CPU (solve + bound) on
    the first mesh certifying it, and over every bound-driven mesh up to it; at the
    adaptive's smallest bound where it never meets the target; extrapolated where the
    uniform meshes stop short."""
    uni = [
        _uniform_row(1, 100, 0.4, 1.0, True),
        _uniform_row(2, 400, 0.2, 2.0, True),
        _uniform_row(3, 900, 0.13, 3.0, False),  # the exact stop's mesh, not on the path
        _uniform_row(4, 1600, 0.1, 4.0, True),
    ]
    ada = [
        dict(dofs=100, error=0.3, eta=0.4, cpu=0.5, estimator="equilibrated"),
        dict(dofs=300, error=0.12, eta=0.3, cpu=1.0, estimator="residual"),
        dict(dofs=700, error=0.09, eta=0.1, cpu=2.0, estimator="equilibrated"),
    ]
    out = bench.certified(0.1, uni, ada)
    assert out["certified_eta"] == 0.1 and out["adaptive_certified_dofs"] == 700
    assert out["uniform_certified_dofs"] == 1600
    assert out["uniform_bound_last_cpu"] == 6.0  # 4 + its bound 2
    assert out["uniform_bound_every_cpu"] == 1.5 + 3.0 + 6.0  # the path: ×1, ×2, ×4
    assert out["certified_last_cpu"] == round(2.0 / 6.0, 3)
    assert out["certified_every_cpu"] == round(2.0 / 10.5, 3)
    # never certified at the target: at its last bound's η, which the exact stop's mesh meets
    ada[-1]["eta"] = 0.15
    out = bench.certified(0.1, uni, ada)
    assert out["certified_eta"] == 0.15 and out["uniform_certified_dofs"] == 900
    assert out["uniform_bound_every_cpu"] == 1.5 + 3.0 + 4.5
    uni.append(_uniform_row(5, 2500, 0.16, 10.0, True))  # a bound rising on a finer mesh
    assert bench.certified(0.1, uni, ada)["uniform_bound_every_cpu"] == 1.5 + 3.0 + 4.5
    uni.pop()
    ada.append(dict(dofs=1500, error=0.05, eta=0.18, cpu=3.0, estimator="equilibrated"))
    assert bench.certified(0.1, uni, ada)["adaptive_certified_dofs"] == 700  # the smallest η
    ada.pop()
    # the uniform meshes stop short: the last two extrapolated (power law in η)
    ada[-1]["eta"] = 0.05
    out = bench.certified(0.05, uni, ada)
    assert out["uniform_extrapolated"] and "uniform_certified_dofs" not in out
    s = math.log(0.13 / 0.05) / math.log(0.13 / 0.1)  # 0.05 on the line through ×3, ×4
    assert out["uniform_bound_last_cpu"] == pytest.approx(4.5 * (6.0 / 4.5) ** s, rel=1e-3)
    assert out["uniform_bound_every_cpu"] == pytest.approx(
        1.5 + 3.0 + 6.0 + 4.5 * (6 / 4.5) ** s, rel=1e-3
    )
    assert bench.certified(0.1, uni, ada[1:2]) == {}  # no bounded level


def test_repeated_runs_take_the_median_of_each_clock(bench) -> None:
    """``--repeat``: each row's clocks are the medians of its repeats, its DoFs and errors
    those of the runs; repeats that made other meshes are refused."""
    runs = [
        [dict(dofs=10, error=0.2, cpu=c, seconds=c + 1), dict(dofs=40, error=0.1, cpu=2 * c)]
        for c in (3.0, 1.0, 2.0)
    ]
    rows = bench.median_rows(runs)
    assert rows == [
        dict(dofs=10, error=0.2, cpu=2.0, seconds=3.0, repeats=3),
        dict(dofs=40, error=0.1, cpu=4.0, repeats=3),
    ]
    assert bench.median_rows(runs[:1]) == runs[0]  # one run: its rows as they are
    runs[1][1]["dofs"] = 41
    with pytest.raises(AssertionError, match="other meshes"):
        bench.median_rows(runs)


def test_bench_repeats_every_run_and_writes_the_medians(bench, tmp_path, monkeypatch) -> None:
    """The script end to end with ``--repeat 2``: every uniform mesh and level twice, the CSV
    rows marked with their repeats and the ratio row made of the medians."""
    import csv
    import sys

    out = tmp_path / "tta.csv"
    argv = ["bench_time_to_accuracy.py", "ex9", "--target", "5e-2", "--max-dofs", "20000"]
    argv += ["--variant", "g3:adapt.growth=3", "--uniform", "uniform:", "--repeat", "2"]
    monkeypatch.setattr(sys, "argv", [*argv, "--out", str(out)])
    bench.main()
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    runs = [r for r in rows if r["run"] in ("uniform", "g3")]
    assert runs and all(r["repeats"] == "2" for r in runs)
    ratio = next(r for r in rows if r["run"] == "ratio")
    uni = next(r for r in runs if r["run"] == "uniform" and float(r["error"]) <= 5e-2)
    ada = next(r for r in runs if r["run"] == "g3" and float(r["error"]) <= 5e-2)
    assert float(ratio["first_reaching_cpu"]) == round(float(ada["cpu"]) / float(uni["cpu"]), 3)
