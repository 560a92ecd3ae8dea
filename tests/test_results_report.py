"""demos/make_results.py: the report's numbers come from the study CSVs, and missing
results are reported as missing instead of crashing."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SQUARE = ROOT / "configs" / "signorini_square.yaml"


def _report(results: Path, out: Path) -> str:
    proc = subprocess.run(
        [sys.executable, "demos/make_results.py", "--results", str(results), "--out", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    return out.read_text()


def _demo_module(name: str):
    """demos/<name>.py imported as a module (demos/ is not a package)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, ROOT / "demos" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_report_without_results_says_what_is_missing(tmp_path: Path) -> None:
    text = _report(tmp_path / "none", tmp_path / "R.md")
    assert text.startswith("# Results")
    # §1, A, D, Hertz, §3, §3 at scale, §4, ex9, step-41 and its cold start at scale, §6, §7,
    # §8, §9 cost, §11's line
    # search, strip, refinement, stability map at finite strain, predictor, adaptivity and
    # the large ball at finite strain, the ironing benchmark, adaptivity against a curved
    # obstacle, friction between bodies, the kinking tube, §12 bounds, §13's baselines and
    # their stability map, §14 time to accuracy, §15 hp and §16 long paths
    assert text.count("*Not available:") == 31


def test_report_stability_section_reads_the_csv(tmp_path: Path) -> None:
    """A small stability study (two cases, a failing one) → its iterations, outcomes and the
    failure table in the report."""
    from contact.app.study import run_study

    study = {
        "name": "stability",
        "scene": str(SQUARE),
        "set": ["mesh.cells=[8,8]"],
        "axes": {"method": ["fb", "min", "blend", "vinewtonrsls", "vinewtonssls"]},
        "cases": {"(g) level 1": {"level": 1}, "(g) level 2": {"level": 2, "max_it": 2}},
        "charts": ["stability"],
    }
    rows, _ = run_study(study, tmp_path / "res" / "stability", verbose=False)
    text = _report(tmp_path / "res", tmp_path / "R.md")
    section = text.split("## 3.", 1)[1].split("## 4.", 1)[0]
    ok = [r for r in rows if r["converged"]]
    assert f"{len(ok)} of {len(rows)} runs converge" in section
    # linear solves
    fb = [r["newton_iterations"] + r["polish_solves"] for r in rows if r["method"] == "fb"]
    assert f"fb {min(fb)}–{max(fb)}" in section
    failed = [r for r in rows if not r["converged"]]
    assert failed and all(
        f"| {r['case']} | {r['method']} | max iterations | 2 |" in section for r in failed
    )


def test_report_guaranteed_bounds_section_reads_the_csvs(tmp_path: Path) -> None:
    """§12 (demos/bench/bench_equilibrated.py, bench_stopping.py): the effectivity ranges of
    both estimators per problem, whether η ≥ error on every level, the cost rows and each
    stopping mode's CPU spread come from the CSVs; the chart is drawn from them."""
    eq = tmp_path / "res" / "equilibrated"
    eq.mkdir(parents=True)
    head = "problem,ranks,strategy,level,dofs,error,eta,effectivity,residual_effectivity"
    lines = [head]
    for level, (eff, res) in enumerate([(1.6, 4.0), (1.2, 3.5), (1.3, 3.6), (1.25, 3.4)]):
        lines.append(f"A_P1,1,dorfler,{level},{100 * 2**level},1.0,{eff},{eff},{res}")
    for level, (eff, res) in enumerate([(1.1, 9.0), (0.9, 9.5)]):  # a level below the error
        lines.append(f"C_P2,1,dorfler,{level},{50 * 2**level},1.0,{eff},{eff},{res}")
    (eq / "effectivity.csv").write_text("\n".join(lines) + "\n")
    (eq / "cost.csv").write_text(
        "dim,ranks,dofs,backend,reconstruction_cpu,solve_cpu,ratio_cpu,estimate_cpu,"
        "estimate_ratio_cpu,residual_cpu,residual_ratio_cpu\n"
        "2,1,1038961,compiled,2.9,3.0,0.97,7.2,2.4,0.9,0.3\n"
    )
    (eq / "cost_3d.csv").write_text(
        "dim,ranks,dofs,backend,reconstruction_cpu,solve_cpu,ratio_cpu,estimate_cpu,"
        "estimate_ratio_cpu,residual_cpu,residual_ratio_cpu\n"
        "3,1,520192,compiled,30.0,3.0,10.0,45.0,15.0,3.0,1.0\n"
        "3,1,520192,flow,24.0,3.0,8.0,39.0,13.0,3.0,1.0\n"
        "3,1,520192,lowest,3.9,3.0,1.3,10.5,3.5,3.0,1.0\n"
    )
    (eq / "effectivity_3d.csv").write_text(
        "ranks,n,dofs,backend,error,eta,effectivity\n"
        "1,8,1377,compiled,0.1,0.125,1.25\n1,8,1377,flow,0.1,0.13,1.3\n"
    )
    (eq / "effectivity_lowest.csv").write_text(
        "problem,ranks,level,dofs,error,eta,effectivity\n"
        "A_P1,1,2,300,0.1,0.16,1.6\nA_P1,1,3,600,0.1,0.155,1.55\nA_P1,1,4,900,0.1,0.15,1.5\n"
    )
    stop = tmp_path / "res" / "stopping"
    stop.mkdir()
    (stop / "stopping.csv").write_text(
        "run,mode,tol,dofs,error,krylov_iterations,cpu_solve,cpu\n"
        "0,fixed,0.002,413467,0.00155,251,3.6,15.9\n"
        "0,adaptive,0.002,447055,0.00149,48,2.1,14.1\n"
        "1,fixed,0.002,413467,0.00155,251,3.5,15.5\n"
        "1,adaptive,0.002,447055,0.00149,48,2.2,14.6\n"
    )
    (eq / "estimators.csv").write_text(
        "run,scene,estimator,tol,levels,dofs,eta,error,effectivity,cpu\n"
        "0,a.yaml,residual,0.004,18,1230966,0.0034,0.00094,3.57,54.6\n"
        "0,a.yaml,equilibrated,0.004,13,93637,0.0037,0.0033,1.13,4.3\n"
    )
    text = _report(tmp_path / "res", tmp_path / "R.md")
    section = text.split("## 12.", 1)[1]
    assert "stops on the equilibrated bound at 93637 DoFs (4.3 s CPU)" in section
    assert "overstates the error 3.57×, refines on to 1230966 DoFs (54.6 s CPU)" in section
    assert "| A_P1 | 1 | 4 | 800 | 1.2–1.6 | 1.25 | yes | 3.4–4 | 3.4 |" in section
    assert "| C_P2 | 1 | 2 | 100 | 0.9–1.1 | – | no (levels [1]) | 9–9.5 | – |" in section
    assert "the flux reconstruction 2.9 s = 0.97× (target 1×)" in section
    assert "the residual estimate 0.9 s = 0.3×" in section
    assert "the flux reconstruction 30 s = 10× (target 2×)" in section
    assert (
        "(`reconstruct_flux(backend='flow')`, an API argument) the reconstruction 24 s = 8×, "
        "the whole estimate 39 s = 13×" in section
    )
    assert (
        "(`reconstruct_flux(degree=0)`: σ_h ∈ RT_0, docs/theory.md §9) the reconstruction "
        "3.9 s = 1.3×, the whole estimate 10.5 s = 3.5×" in section
    )
    assert "--uniform3d`): 1377 DoFs: compiled 1.250, flow 1.300." in section
    assert (
        "**Effectivity of the lowest-order flux (`estimator: equilibrated_rt0`, σ_h ∈ RT_0), 2D**"
        " (the same adaptive loops, `bench_equilibrated.py --backend lowest`; η ≥ error on every "
        "level unless stated), from level 3: A_P1 1.5–1.55." in section
    )
    assert "| fixed | 2 | 251 | 3.5–3.6 | 15.5 / 15.7 / 15.9 | 413467 |" in section
    assert "| adaptive | 2 | 48 | 2.1–2.2 | 14.1 / 14.3 / 14.6 | 447055 |" in section
    assert (eq / "effectivity.png").stat().st_size > 0


def test_design_measurements_are_in_the_report_and_out_of_the_docstrings() -> None:
    """Timings that decided a design choice live in RESULTS.md §10 (written by make_results),
    and the docstrings of the modules listed there point to it instead of quoting them."""
    report = _demo_module("make_results")
    assert report.design_measurements() in (ROOT / "demos" / "RESULTS.md").read_text()
    for module in (
        "output/vtk",
        "output/drawing",
        "adaptivity/refine",
        "adaptivity/energy_error",
        "models/problem",
        "drivers/sequencing",
    ):
        text = (ROOT / "contact" / f"{module}.py").read_text()
        assert "demos/RESULTS.md §10" in text, module
        for quoted in (
            "12.5 s",
            "0.17 s",
            "4.6 s",
            "5.4 s",
            "0.34 s",
            "20 s at",
            "50 s",
            "2.2 s",
            "1.73 s",
            "4.3 s",
            "44 s",
        ):
            assert quoted not in text, (module, quoted)


def test_bench_scripts_live_in_demos_bench_and_run_bench_finds_them() -> None:
    """`make bench` (demos/run_bench.py) runs the benchmark scripts from demos/bench/."""
    run_bench = _demo_module("run_bench")
    scripts = [cmd[1] for step in ("newton", "adaptive", "hertz") for cmd in run_bench.STEPS[step]]
    assert scripts == [f"demos/bench/bench_{name}.py" for name in ("newton", "adaptive", "hertz")]
    for script in scripts:
        proc = subprocess.run(
            [sys.executable, script, "--help"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert proc.returncode == 0 and "usage:" in proc.stdout, proc.stderr


def test_run_bench_keep_going_runs_past_a_failure_and_labels_portably(
    tmp_path: Path, monkeypatch
) -> None:
    """``run_bench --keep-going`` runs every command after a failed one and exits with the first
    failure's code; without it the run stops there. timings.csv names the venv's programs by
    their name, not by the checkout's absolute path."""
    run_bench = _demo_module("run_bench")
    fail = [run_bench.PY, "-c", "raise SystemExit(3)"]
    ok = [run_bench.MPIRUN, "-n", "1", run_bench.PY, "-c", "pass"]
    monkeypatch.setattr(run_bench, "ROOT", tmp_path)
    monkeypatch.setattr(run_bench, "STEPS", {"a": [fail], "b": [ok], "report": []})
    (tmp_path / "demos").mkdir()
    timings = tmp_path / "demos" / "results" / "timings.csv"

    monkeypatch.setattr(sys, "argv", ["run_bench", "--only", "a", "b"])
    assert run_bench.main() == 3
    assert list(run_bench._read(timings)) == ["python -c raise SystemExit(3)"]

    timings.unlink()
    monkeypatch.setattr(sys, "argv", ["run_bench", "--only", "a", "b", "--keep-going"])
    assert run_bench.main() == 3
    assert list(run_bench._read(timings)) == [
        "python -c raise SystemExit(3)",
        "mpirun -n 1 python -c pass",
    ]


def test_refine_floor_sentence_reads_the_kernel_csvs(tmp_path: Path) -> None:
    """§9's floor sentence (bench_kernels.py --only floor): its ratios come from the CSVs,
    and it says a refinement outside dolfinx would not help only when create_mesh +
    assembly exceed half the solve."""
    report = _demo_module("make_results")
    assert report.refine_floor(tmp_path) == ""

    def write(
        name: str, ranks: int, refine: float, create: float, assembly: float, solve: float
    ) -> None:
        lines = (
            ["kernel,ranks,size,path,seconds,check"]
            + [
                f"floor,{ranks},1234321,{path},{t},{t / solve:.3f}"
                for path, t in (("refine", refine), ("create_mesh", create), ("assembly", assembly))
            ]
            + [f"floor,{ranks},1234321,solve,{solve},16"]
        )
        (tmp_path / name).write_text("\n".join(lines) + "\n")

    write("kernels_floor.csv", 1, 4.0, 10.0, 1.0, 5.0)
    write("kernels_floor_np2.csv", 2, 4.5, 6.0, 0.75, 5.0)
    text = report.refine_floor(tmp_path)
    assert text.startswith(" Nor would a refinement written outside dolfinx help")
    assert "1.3–2.5× `dolfinx.mesh.refine`" in text  # create_mesh over refine: 6/4.5, 10/4
    assert "at least 1.00× the solve" in text  # min(0.8 + 0.2, 0.9 + 0.15)
    assert "refinement 1.35×" in text  # min(2.0 + 0.2, 1.2 + 0.15)
    write("kernels_floor_np2.csv", 2, 4.5, 1.5, 0.75, 5.0)
    assert report.refine_floor(tmp_path).startswith(
        " A refinement written outside dolfinx might help"
    )


def test_bench_friction_runs_end_to_end_quick(tmp_path: Path) -> None:
    """demos/bench/bench_friction.py --quick (make bench, RESULTS friction section) runs through;
    its tangential-forms study warm-starts every form from the frictionless solution (it once
    failed there when a guess on another mesh became an error), and the hsw form converges
    from both starts on every case."""
    import csv

    proc = subprocess.run(
        [sys.executable, "demos/bench/bench_friction.py", "--quick", "--out", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    with open(tmp_path / "forms.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["start"] for r in rows} == {"cold", "frictionless"}
    hsw = [r for r in rows if r["form"] == "hsw"]
    assert len(hsw) == 24 and all(r["converged"] == "True" for r in hsw)


def test_bench_hertz_runs_end_to_end_on_small_meshes(tmp_path: Path) -> None:
    """demos/bench/bench_hertz.py (make bench, RESULTS §6) on small meshes: every method
    converges on both final meshes, and fb's cold 2D start is compared across all three
    kinds of ``solver.linear`` (the script once broke when the default options changed)."""
    import csv

    proc = subprocess.run(
        [
            sys.executable,
            "demos/bench/bench_hertz.py",
            "--set",
            "adapt.max_dofs=20000",
            "--out",
            str(tmp_path),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    with open(tmp_path / "final_mesh_methods.csv", newline="") as fh:
        finals = list(csv.DictReader(fh))
    assert {r["scene"] for r in finals} == {"hertz_2d", "hertz_3d"}
    assert all(r["converged"] == "True" for r in finals)
    cold_fb_2d = {
        r["linear_solver"]
        for r in finals
        if (r["scene"], r["method"], r["start"]) == ("hertz_2d", "fb", "cold")
    }
    assert cold_fb_2d == {"direct", "gamg", "bcgs"}


def test_report_baselines_sections_read_the_csvs(tmp_path: Path) -> None:
    """§13 (demos/bench/bench_baselines.py, configs/studies/stability_baselines.yaml): the
    parameter each method needs for fb's accuracy (|||u − u_fb||| ≤ 1 % of fb's error), the
    time ratio then, the observed penalty order and the failures of a small stability study,
    each explained."""
    from contact.app.study import run_study

    res = tmp_path / "res"
    (res / "baselines").mkdir(parents=True)
    head = (
        "problem,dofs,h_min,method,theta,parameter,value,converged,reason,newton_iterations,"
        "outer_iterations,coarse_iterations,krylov_iterations,linear_solver,seconds,fb_seconds,"
        "ratio,error,error_fb,dist_fb,norm_fb,penetration,penetration_rel,force_rel"
    )
    fb = "A,100,0.1,fb,,,,True,converged_fnorm_abs,5,0,0,5,direct,1.0,1.0,1.0,0.1,0.1,0,2.0,0,0,0"
    lines = [head, fb]
    # |||u − u_fb||| = 2 dist: ≤ 1 % of fb's error 0.1 from ε₀ = 1000 on
    for eps, dist in ((10.0, 1e-2), (100.0, 1e-3), (1000.0, 1e-4)):
        lines.append(
            f"A,100,0.1,penalty,,epsilon0,{eps},True,converged_fnorm_abs,5,1,0,5,direct,"
            f"{1 + eps / 1e4},1.0,{1 + eps / 1e4},0.1,0.1,{dist},2.0,{dist},{dist},0"
        )
    (res / "baselines" / "A.csv").write_text("\n".join(lines) + "\n")
    # two bodies (Cattaneo–Mindlin): penalty and augmented Lagrangian only, no Nitsche rows
    two = [line.replace("A,", "cattaneo,", 1) for line in lines[1:]]
    (res / "baselines" / "cattaneo.csv").write_text("\n".join([head, *two]) + "\n")
    study = {
        "name": "stability_baselines",
        "scene": str(SQUARE),
        "set": ["mesh.cells=[8,8]", "solver.max_it=20"],
        "axes": {"method": ["fb", "penalty", "nitsche"]},
        "cases": {"(g) level 1": {"level": 1}, "(r) A, parameter 1.0e-3": {"parameter": 1e-3}},
        "charts": ["stability"],
    }
    rows, _ = run_study(study, res / "stability_baselines", verbose=False)
    text = _report(res, tmp_path / "R.md")
    section = text.split("## 13.", 1)[1]
    assert "| A | 100 | penalty | ε₀ = 1e+03 | 1.10 | 5 |" in section
    assert "| cattaneo | 100 | penalty | ε₀ = 1e+03 | 1.10 | 5 |" in section
    cattaneo = section.split("### Cattaneo–Mindlin", 1)[1].split("###", 1)[0]
    assert "| 100 | penalty |" in cattaneo and "| 100 | nitsche" not in cattaneo
    assert "|||u − u_fb||| ∝ ε₀^-1.00" in section
    failed = [r for r in rows if not r["converged"]]
    assert [(r["case"], r["method"]) for r in failed] == [("(r) A, parameter 1.0e-3", "nitsche")]
    assert "| (r) A, parameter 1.0e-3 | nitsche | max iterations | 20 |" in section
    assert "not yet explained" not in section


def test_report_hp_section_reads_the_csvs(tmp_path: Path) -> None:
    """§15 (demos/bench/bench_hp.py): the summary's figures per problem and method, the
    exponential fit of the hp runs and the chart, from the CSVs."""
    hp = tmp_path / "res" / "hp"
    hp.mkdir(parents=True)
    keys = "problem,method,target,reached,unknowns,seconds,error,levels,effectivity_min,"
    keys += "effectivity_max_past_3,bound_holds,stop,exp_rate_b,exp_fit_r2,"
    keys += "unknowns_ratio_P2,seconds_ratio_P2,cpu_seconds,cpu_ratio_P2"
    (hp / "summary.csv").write_text(
        keys
        + "\nC,hp,1e-06,True,2141,39.5,7.5e-07,29,1.03,1.1,True,eta,1.695,0.993,17.7,0.45,6.0,0.5"
        + "\nC,h-P2,1e-06,False,37907,17.6,1.1e-05,14,1.1,1.4,True,dofs,,,1.0,1.0,3.0,1.0\n"
    )
    lines = ["problem,method,level,unknowns,error,eta,effectivity,seconds,p_max,p_min,cpu_seconds"]
    for k in range(4):
        lines.append(
            f"C,hp,{k},{100 * (k + 1)},{10.0**-k},{2 * 10.0**-k},2.0,{k + 1},{k + 1},1,{k / 2}"
        )
        lines.append(f"C,h-P2,{k},{400 * (k + 1)},{10.0 ** (-k / 2)},1,1.1,{k + 1},2,2,{k / 4}")
    (hp / "levels.csv").write_text("\n".join(lines) + "\n")
    (hp / "hertz_summary.csv").write_text(
        "method,target,reached,level,unknowns,a_error,p0_error,cpu_seconds,levels,"
        "unknowns_ratio_P1,cpu_ratio_P1\nhp-p4,0.005,True,5,11676,0.00286,0.00445,5.17,14,"
        "1.82,0.22\n"
    )
    (hp / "solvers.csv").write_text(
        "p,solver,unknowns,cells,iterations,converged,setup_cpu,solve_cpu,cpu,"
        "relative_residual,cpu_ratio_direct\n6,p1-patch,37249,2048,12,True,0.41,0.61,1.02,"
        "6e-11,5.37\n"
    )
    cube = ["level,unknowns,cells,p_min,p_max,error,eta,effectivity,cpu_seconds"]
    for k in range(5):
        cube.append(f"{k},{100 * 4**k},{50 * 4**k},1,3,{0.2 / 2**k},{0.3 / 2**k},1.5,{k + 1}")
    (hp / "three_d.csv").write_text("\n".join(cube) + "\n")
    text = _report(tmp_path / "res", tmp_path / "R.md")
    section = text.split("## 15. hp-adaptivity", 1)[1]
    assert "| hp-p4 | yes | 5 | 11676 | +0.29 % | +0.45 % | 5.17 | 1.82 | 0.22 |" in section
    assert "| 2048 | 6 | 37249 | p1-patch | 12 | 0.410 | 0.610 | 5.37 |" in section
    # CPU s (unknowns) at the first level at or below each error: hp's level 3, P2's none
    assert "| C | 0.001 | 1.50 (400) | – |" in section
    assert "| 4 | 25600 | 12800 | 1–3 | 0.0125 | 0.0187 | 1.500 | 5.0 |" in section
    assert "η ≥ error on every level: yes" in section and "N^−0.50" in section
    assert (
        "| C | hp | 1e-06 | yes | 2141 | 7.5e-07 | 39.50 | 6.00 | 17.7 | 0.45 | 0.50 | 1.1 | yes"
        " | 29 |" in section
    )
    assert "| C | h-P2 | 1e-06 | no (budget) | 37907 |" in section
    assert "log(error) ≈ c − 1.695 N^{1/3}" in section and "r² = 0.993" in section
    assert (hp / "hp.png").read_bytes()[:4] == b"\x89PNG"


def test_every_prose_call_fills_exactly_its_blocks_placeholders() -> None:
    """Statically, for every ``prose(section, block, **values)`` of demos/make_results.py:
    the block exists in demos/results_templates/<section>.md and its placeholders are the
    call's keywords, so that no branch a test run does not reach fails on a missing or a
    forgotten name; and every block is used."""
    import ast
    import re
    import string

    module = _demo_module("make_results")
    tree = ast.parse((ROOT / "demos" / "make_results.py").read_text(encoding="utf-8"))
    used = set()
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "prose"):
            continue
        section, block = (a.value for a in node.args)
        text = module.template_blocks(section)[block]
        names = {
            m.group("named") or m.group("braced")
            for m in string.Template.pattern.finditer(text)
            if m.group("named") or m.group("braced")
        }
        assert names == {k.arg for k in node.keywords}, (section, block)
        used.add((section, block))
    for path in (ROOT / "demos" / "results_templates").glob("*.md"):
        if path.name != "README.md":
            for block in re.findall(r"^<!-- (\w+) -->$", path.read_text(), re.MULTILINE):
                assert (path.stem, block) in used, f"{path.name}: block {block} is not used"


def test_report_time_to_accuracy_section_reads_the_csv(tmp_path: Path) -> None:
    """§14 (demos/bench/bench_time_to_accuracy.py): per scene and variant the last level, the
    ratios adaptive / uniform and the extrapolated one, the honest summary and the chart
    of error against CPU seconds, from the CSV."""
    res = tmp_path / "res"
    res.mkdir()
    head = "scene,run,level,dofs,error,seconds,cpu,variant,target,first_reaching_seconds,"
    head += "interpolated_seconds,first_reaching_cpu,interpolated_cpu,"
    head += "uniform_extrapolated_cpu,extrapolated_cpu"
    lines = [head]
    for k, (dofs, err, cpu) in enumerate([(65, 0.19, 0.04), (225, 0.12, 0.05)]):
        lines.append(f"lshape,uniform,{2**k},{dofs},{err},{cpu},{cpu},,,,,,,,")
    for run, cpu in (("adaptive", 1.0), ("dorfler", 1.2)):
        lines.append(f"lshape,{run},0,65,0.19,0.1,0.1,,,,,,,,")
        lines.append(f"lshape,{run},1,900,0.0019,{cpu},{cpu},,,,,,,,")
    lines.append("lshape,ratio,,,0.12,,,adaptive,0.002,2.0,2.0,0.4,0.4,944.2,0.0112")
    lines.append("lshape,ratio,,,0.12,,,dorfler,0.002,2.0,2.0,0.47,0.44,944.2,0.0101")
    (res / "time_to_accuracy.csv").write_text("\n".join(lines) + "\n")
    text = _report(res, tmp_path / "R.md")
    section = text.split("## 14.", 1)[1].split("## 15.", 1)[0]
    assert "**lshape** to energy error 2.0e-03 (the uniform meshes stop short" in section
    assert (
        "| adaptive | 2 | 900 | 1.900e-03 | 1.00 | 0.40 / 0.40 | 0.0112 (89× faster) | — |"
        in section
    )
    assert (
        "| dorfler | 2 | 900 | 1.900e-03 | 1.20 | 0.47 / 0.44 | 0.0101 (99× faster) | — |"
        in section
    )
    assert "would need about 944 s CPU for 2e-3" in section and "89× to 99× faster" in section
    assert "`dorfler` `adapt.growth=1`" in section
    assert (res / "time_to_accuracy.png").read_bytes()[:4] == b"\x89PNG"


def test_report_time_to_accuracy_holds_degree_two_and_hp_against_every_uniform_run(
    tmp_path: Path,
) -> None:
    """§14 with the uniform P2 reference and the variants p2 and hp: the tables' ratios are
    against uniform P1, a column gives the speed-up against uniform P1 and against the
    fastest uniform run, and the summary names the fastest of p2 and hp per scene with both
    speed-ups and the fastest P1 variant's."""
    res = tmp_path / "res"
    res.mkdir()
    head = "scene,run,level,dofs,error,seconds,cpu,variant,reference,target,"
    head += "first_reaching_seconds,interpolated_seconds,first_reaching_cpu,interpolated_cpu,"
    head += "speedup_cpu,best_reference,speedup_vs_best_cpu"
    lines = [head]
    for run, points in (
        ("uniform", [(153, 0.087, 0.06), (260281, 0.00195, 2.7)]),
        ("uniform_p2", [(561, 0.0046, 0.05), (2145, 0.0016, 0.1)]),
        ("adaptive", [(153, 0.087, 0.08), (260000, 0.00199, 8.1)]),
        ("p2", [(561, 0.0046, 0.1), (1900, 0.0015, 0.25)]),
        ("hp", [(153, 0.087, 0.09), (900, 0.0018, 0.54)]),
    ):
        for k, (dofs, err, cpu) in enumerate(points):
            lines.append(f"A,{run},{k},{dofs},{err},{cpu},{cpu}" + "," * 10)
    for variant, (p1, p2) in {
        "adaptive": (3.0, 81.0),
        "p2": (0.1, 2.5),
        "hp": (0.2, 5.4),
    }.items():
        best = 1 / p2
        for reference, ratio in (("uniform", p1), ("uniform_p2", p2)):
            lines.append(
                f"A,ratio,,,0.002,,,{variant},{reference},0.002,{ratio},{ratio},{ratio},{ratio},"
                f"{1 / ratio:.4g},uniform_p2,{best:.4g}"
            )
    (res / "time_to_accuracy.csv").write_text("\n".join(lines) + "\n")
    text = _report(res, tmp_path / "R.md")
    section = text.split("## 14.", 1)[1].split("## 15.", 1)[0]
    # the ratio columns against uniform P1; the speed-ups against P1 and the fastest uniform
    assert (
        "| p2 | 2 | 1900 | 1.500e-03 | 0.25 | 0.10 / 0.10 | — | 10.00× / 0.40× (uniform_p2) |"
        in (section)
    )
    assert "| uniform_p2 | 2 | 2145 | 1.600e-03 | 0.10 | — | — | — |" in section
    assert (
        "A to 2e-03: `p2` 10.0× faster than uniform P1, 0.40× the fastest uniform run "
        "(uniform_p2); the fastest P1 variant 0.33×" in section
    )
    # the recommendation: p2 is ≥ 5× faster than uniform P1, and slower than uniform P2
    assert "**Recommended for a solution like problem A's: `p2`**" in section
    assert "10.0× faster than uniform P1 to 2e-03 (the fastest P1 variant: 0.33×)" in section
    assert "(uniform_p2) it is 0.40× (below 1: slower)" in section
    assert (res / "time_to_accuracy.png").read_bytes()[:4] == b"\x89PNG"


def test_report_step41_cold_start_reads_the_alternated_pairs(tmp_path: Path) -> None:
    """§5's step-41 cold start: the alternated pairs (bench_cold.py --pair) in a table of
    their own, and deal.II's median CPU of them the reference of the × deal.II column."""
    res = tmp_path / "res"
    (res / "cold").mkdir(parents=True)
    head = "cells,dofs,ranks,method,variant,forcing,warm_start,converged,newton,krylov,"
    head += "krylov_per_step,gamg_setups,residual,cpu_s,wall_s,cpu_vs_first,ref_its,ref_cpu_s,"
    head += "ratio_cpu_vs_one_solve,max_diff_vs_first,dealii_cpu_s,ratio_cpu_vs_dealii"
    (res / "cold" / "step41.csv").write_text(
        head + "\n256,66049,1,min,new,active_set,True,True,40,96,2.4,18,4e-13,2.0,2.1,1.0,14,"
        "0.15,13.3,0.0,,\n"
    )
    head = "cells,dofs,pair,method,converged,max_it,newton,krylov,cpu_s,dealii_dofs,"
    head += "dealii_returncode,dealii_newton,dealii_cg,dealii_cpu_s,ratio_cpu_vs_dealii"
    (res / "cold" / "pair_step41_256.csv").write_text(
        head + "\n256,66049,1,min,True,50,40,96,1.7,66049,0,36,162,5.5,0.309"
        "\n256,66049,2,min,True,50,40,96,1.7,66049,0,36,162,4.5,0.378\n"
    )
    text = _report(res, tmp_path / "R.md")
    section = text.split("from a cold start, 66k to 1M DoFs", 1)[1].split("## 6.", 1)[0]
    assert "256²: 5 s, 36 Newton and 162 CG iterations" in section  # the pairs' median
    assert "| 256² | 66049 | new (active_set) | 40 | 96 (2.4) | 18 | 2 | 13.3 | 0.4 | True |" in (
        section
    )
    assert "| 256² | 2 | 40, 96, 1.7 | 36, 162, 4.5 | 0.378 |" in section


def test_report_ex9_at_equal_certification_reads_the_csv(tmp_path: Path) -> None:
    """§14's ex9 at equal certification (bench_time_to_accuracy.py --uniform-bound): per
    variant its certified level and the three ratios against uniform P1, and whether the
    uniform exact stop's bound certifies the target, from the CSV."""
    res = tmp_path / "res"
    (res / "adaptive_cost").mkdir(parents=True)
    lshape = "scene,run,level,dofs,error,seconds,cpu,variant,target\n"
    lshape += "lshape,uniform,1,65,0.19,0.04,0.04,,\nlshape,adaptive,0,65,0.19,0.1,0.1,,\n"
    (res / "time_to_accuracy.csv").write_text(lshape)
    cols = (
        "scene,run,level,dofs,error,cpu,bound_cpu,eta,estimator,certified,variant,reference,"
        "target,first_reaching_cpu,interpolated_cpu,certified_eta,adaptive_certified_dofs,"
        "adaptive_certified_error,adaptive_certified_cpu,uniform_certified_dofs,"
        "uniform_bound_last_cpu,uniform_bound_last_interp_cpu,uniform_bound_every_cpu,"
        "certified_last_cpu,certified_last_interp_cpu,certified_every_cpu,"
        "budget_first_reaching_cpu,budget_interpolated_cpu"
    )
    tail = "," * 18
    lines = [
        cols,
        f"ex9,uniform,1,1000,0.005,1.0,0.5,0.0055,equilibrated,True{tail}",
        f"ex9,uniform,2,4000,0.0035,4.0,1.5,0.0038,equilibrated,True{tail}",
        f"ex9,res3,0,500,0.01,0.5,0.0,0.02,residual,{tail}",
        f"ex9,res3,1,3000,0.0039,5.0,0.0,0.0039,equilibrated,{tail}",
        "ex9,ratio,,,0.004,,,,,,res3,uniform,0.004,1.25,1.2,0.004,3000,0.0039,5.0,4000,5.5,"
        "5.25,7.5,0.909,0.952,0.667,1.05,1.02",
        "ex9,ratio,,,0.004,,,,,,res3,uniform_p2,0.004,0.5,0.5,0.004,3000,0.0039,5.0,100,0.2,"
        "0.2,0.3,25.0,25.0,16.7,,",
    ]
    (res / "adaptive_cost" / "time_to_accuracy_ex9_certified.csv").write_text(
        "\n".join(lines) + "\n"
    )
    text = _report(res, tmp_path / "R.md")
    section = text.split("**ex9 at equal certification**", 1)[1].split("**Memory", 1)[0]
    stop = "Uniform P1 stops on the exact error at 4,000 DoFs (error 3.500e-03, 4.00 s CPU)"
    assert stop in section
    assert "3.800e-03 (1.50 s more), certifies it already." in section
    row = (
        "| `res3` | uniform P1 | 2 | 3,000 | 3.900e-03 | 4.000e-03 | 5.00 | 1.25 / 1.20 | "
        "1.05 / 1.02 | 4,000 |"
    )
    assert row + " 5.50 | 0.91 / 0.95 | 7.50 | 0.67 |" in section
    row = "| `res3` | uniform P2 | 2 | 3,000 | 3.900e-03 | 4.000e-03 | 5.00 | 0.50 / 0.50 | – |"
    row += " 100 |"
    assert row + " 0.20 | 25.00 / 25.00 | 0.30 | 16.70 |" in section
