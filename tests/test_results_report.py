"""demos/make_results.py: the report's numbers come from the study CSVs, and missing
results are reported as missing instead of crashing."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SQUARE = ROOT / "configs" / "signorini_square.yaml"


def _report(results: Path, out: Path) -> str:
    proc = subprocess.run([sys.executable, "demos/make_results.py", "--results", str(results), "--out", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return out.read_text()


def test_report_without_results_says_what_is_missing(tmp_path: Path) -> None:
    text = _report(tmp_path / "none", tmp_path / "R.md")
    assert text.startswith("# Results")
    assert text.count("*Not available:") == 13  # §1, A, D, Hertz, §3, §3 at scale, §4, ex9, step-41, §6, §7, §8, §9 cost


def test_report_stability_section_reads_the_csv(tmp_path: Path) -> None:
    """A small stability study (two cases, a failing one) → its iterations, outcomes and the
    failure table in the report."""
    from contact.study import run_study

    study = {"name": "stability", "scene": str(SQUARE), "set": ["mesh.cells=[8,8]"],
             "axes": {"method": ["fb", "min", "blend", "vinewtonrsls", "vinewtonssls"]},
             "cases": {"(g) level 1": {"level": 1}, "(g) level 2": {"level": 2, "max_it": 2}},
             "charts": ["stability"]}
    rows, _ = run_study(study, tmp_path / "res" / "stability", verbose=False)
    text = _report(tmp_path / "res", tmp_path / "R.md")
    section = text.split("## 3.", 1)[1].split("## 4.", 1)[0]
    ok = [r for r in rows if r["converged"]]
    assert f"{len(ok)} of {len(rows)} runs converge" in section
    fb = [r["newton_iterations"] + r["polish_solves"] for r in rows if r["method"] == "fb"]  # linear solves
    assert f"fb {min(fb)}–{max(fb)}" in section
    failed = [r for r in rows if not r["converged"]]
    assert failed and all(f"| {r['case']} | {r['method']} | max iterations | 2 |" in section for r in failed)


def test_bench_scripts_live_in_demos_bench_and_run_bench_finds_them() -> None:
    """`make bench` (demos/run_bench.py) runs the benchmark scripts from demos/bench/."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("run_bench", ROOT / "demos" / "run_bench.py")
    run_bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(run_bench)
    scripts = [cmd[1] for step in ("newton", "adaptive", "hertz") for cmd in run_bench.STEPS[step]]
    assert scripts == [f"demos/bench/bench_{name}.py" for name in ("newton", "adaptive", "hertz")]
    for script in scripts:
        proc = subprocess.run([sys.executable, script, "--help"], cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0 and "usage:" in proc.stdout, proc.stderr
