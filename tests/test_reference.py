"""Reference solutions are declared, never guessed (issue #10 defect 4, issue #14): an
elastic scene without ``reference:`` gets its contact force, reaction, force balance, peak
pressure, contact.csv and pressure.png and no Hertz values; a dummy constant R changes
nothing; ``reference: {type: hertz}`` adds Hertz's values and errors; a bad reference
section is a one-line exit 2."""

import json
import os
import subprocess
import sys
from pathlib import Path

import contact
from contact.base.errors import ConfigError

import pytest

ROOT = Path(__file__).resolve().parents[1]
HERTZ_KEYS = {
    "reference",
    "hertz_a",
    "hertz_p0",
    "a_error",
    "p0_error",
    "a_over_R",
    "contact_half_width",
    "contact_radius",
    "hertz_radius",
}
ELASTIC_KEYS = {
    "contact_force",
    "reaction_force",
    "force_balance_error",
    "peak_pressure",
    "min_gap",
}
SMALL_HERTZ = ["mesh.h=0.2", "mesh.h_contact=0.02", "mesh.zone=0.2"]


def _run(scene, out, *sets):
    cmd = [
        sys.executable,
        "-m",
        "contact.app.cli",
        "run",
        str(scene),
        "-o",
        str(out),
        "-q",
        *(f"--set={s}" for s in sets),
    ]
    return subprocess.run(
        cmd,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )


@pytest.mark.parametrize("sets", [[], ["constants.R=1.0"]], ids=["plain", "dummy-R"])
def test_elastic_scene_without_reference_has_no_hertz_values(tmp_path, sets):
    out = tmp_path / "block"
    proc = _run(ROOT / "configs" / "block_on_plane.yaml", out, "adapt.max_levels=2", *sets)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert ELASTIC_KEYS <= set(summary) and not HERTZ_KEYS & set(summary)
    assert summary["force_balance_error"] < 1e-8 and summary["contact_force"] > 0
    assert summary["peak_pressure"] > summary["contact_force"] / 2.0, (
        "peak above the mean pressure F/|Γ_C|"
    )
    assert {"contact.csv", "pressure.png"} <= {p.name for p in out.iterdir()}
    header = (out / "contact.csv").read_text().splitlines()[0]
    assert header == "x,y,s,lambda_n,gap,active"


def test_declared_hertz_reference_adds_values_and_errors(tmp_path):
    out = tmp_path / "hertz"
    proc = _run(ROOT / "configs" / "hertz_2d.yaml", out, "adapt=none", *SMALL_HERTZ)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reference"] == "hertz" and summary["hertz_radius"] == 1.0
    assert ELASTIC_KEYS | (HERTZ_KEYS - {"contact_radius"}) <= set(summary)
    assert abs(summary["a_error"]) < 0.15 and abs(summary["p0_error"]) < 0.15


def test_hertz_radius_defaults_to_the_built_in_mesh_radius_and_is_required_elsewhere():
    scene = contact.load_scene(
        ROOT / "configs" / "hertz_2d.yaml", SMALL_HERTZ + ["mesh.radius=2.0", "mesh.zone=0.3"]
    )
    assert scene.config.reference.model_dump() == {"type": "hertz", "radius": 2.0}
    block = ROOT / "configs" / "block_on_plane.yaml"
    with pytest.raises(ConfigError, match=r"^reference.radius: required for type hertz"):
        contact.load_scene(block, ["reference={type: hertz}"])
    assert (
        contact.load_scene(block, ["reference={type: hertz, radius: 3}"]).config.reference.radius
        == 3.0
    )


@pytest.mark.parametrize(
    "override,message",
    [
        ("reference={type: hurtz}", "reference.type: 'hurtz' is not one of hertz"),
        ("reference={radius: 1}", "reference.type: required key is missing"),
        ("reference={type: hertz, radius: -1}", "reference.radius: must be > 0"),
        ("reference={type: hertz, R: 1}", "reference.R: unknown key"),
    ],
)
def test_bad_reference_is_one_line(override, message):
    with pytest.raises(ConfigError, match="^" + message.replace("(", r"\(")):
        contact.load_scene(ROOT / "configs" / "hertz_2d.yaml", SMALL_HERTZ + [override])


def test_reference_on_a_scalar_scene_is_bad_input():
    with pytest.raises(ConfigError, match="^reference.type: hertz needs model type elasticity"):
        contact.load_scene(
            ROOT / "configs" / "signorini_square.yaml", ["reference={type: hertz, radius: 1}"]
        )


def test_study_rows_carry_reference_errors_only_for_declared_scenes():
    from contact.app.study import load_study, run_study

    study = {
        "name": "ref",
        "scene": str(ROOT / "configs" / "hertz_2d.yaml"),
        "set": SMALL_HERTZ,
        "axes": {"method": ["min"]},
        "adapt": {"strategy": "none"},
        "warmup": False,
        "cases": {"hertz": {}, "plain": {"set": SMALL_HERTZ + ["reference=null"]}},
    }
    assert load_study(study).accuracy == "hertz_error"
    rows, _ = run_study(study, verbose=False)
    by_case = {r["case"]: r for r in rows}
    assert abs(by_case["hertz"]["p0_error"]) < 0.15 and by_case["hertz"]["hertz_error"] >= abs(
        by_case["hertz"]["a_error"]
    )
    assert by_case["plain"]["p0_error"] == "" and by_case["plain"]["converged"]
