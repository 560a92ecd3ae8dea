"""Penalty and augmented Lagrangian for two bodies through the mortar gap
(contact.solvers.nodal_baselines): both converge with their defaults on the two-body Hertz
scenes (2D and 3D) and agree with Fischer–Burmeister — the penalty to O(1/ε₀) (its order:
test_baselines.py), Uzawa to its tolerance; the interface transmits equal and opposite
forces; serial = 2 ranks; with Coulomb friction on the Cattaneo–Mindlin scene they
reproduce the partial-slip solution as min does.  Coarse meshes: the sweeps are
demos/bench/bench_baselines.py."""

from __future__ import annotations

import os
import subprocess
import sys

import contact
from contact.post.interface import resultants
from contact.post.reference import compare
from contact.setup.posed import posed_of
from contact.setup.run import run_load_path
from contact.solvers.baselines import penetration

import numpy as np
import pytest
from clirun import ROOT

HERTZ_2D = str(ROOT / "configs" / "two_body_hertz_2d.yaml")
HERTZ_3D = str(ROOT / "configs" / "two_body_hertz_3d.yaml")
CATTANEO = str(ROOT / "configs" / "two_body_cattaneo_2d.yaml")
SCENES = {
    "hertz_2d": (HERTZ_2D, ["mesh.h=2.0", "mesh.h_contact=0.1", "mesh.zone=1.0", "adapt=null"]),
    "hertz_3d": (HERTZ_3D, ["mesh.h=0.5", "mesh.h_contact=0.05", "adapt=null"]),
}
#: |F / F_fb − 1| with the default parameter, at most (measured: penalty 2.1e-5 (2D) and
#: 2.2e-4 (3D) at ε₀ = 1e3; Uzawa below 1e-9)
FORCE_TOLERANCE = {"penalty": 1e-3, "augmented_lagrangian": 1e-7}
MPIRUN = os.path.join(os.path.dirname(sys.executable), "mpirun")


@pytest.fixture(scope="module")
def fb_runs() -> dict:
    out = {}
    for name, (path, sets) in SCENES.items():
        scene = contact.load_scene(path, [*sets, "output.verbose=false"])
        out[name] = scene, contact.solve(scene, method="fb", verbose=False)
    return out


@pytest.mark.parametrize("method", list(FORCE_TOLERANCE))
@pytest.mark.parametrize("name", list(SCENES))
def test_two_bodies_converge_with_defaults_and_agree_with_fb(fb_runs, name, method) -> None:
    scene, fb = fb_runs[name]
    r = contact.solve(scene, method=method, verbose=False)
    assert r.converged, (r.reason, r.iterations)
    assert r.method == method and r.n_active == fb.n_active > 0
    rel = abs(r.contact_force / fb.contact_force - 1.0)
    assert rel <= FORCE_TOLERANCE[method], rel
    depth = penetration(r)
    scale = float(np.max(np.abs(fb.u_h.x.array)))
    if method == "augmented_lagrangian":
        assert depth <= 1e-8 * scale and r.outer_iterations >= 2
    else:  # O(1/ε₀) of the displacement scale
        assert 0.0 < depth <= 1e-2 * scale
    # λ_h the method's own nodal multiplier, ≤ 0 on every slave node
    assert float(np.max(r.problem.multiplier(r.contact_residual), initial=0.0)) <= 0.0
    # action = reaction: the forces on the two bodies through the interface balance
    assert resultants(posed_of(scene), r)["interface_balance_error"] < 1e-10


def _bodies_run(tmp_path, nproc: int, name: str) -> dict:
    path, sets = SCENES[name]
    out = tmp_path / f"{name}-np{nproc}.npz"
    cmd = [sys.executable, str(ROOT / "tests" / "bodies_run.py"), str(out), path]
    cmd += [f"--set={s}" for s in [*sets, "output.verbose=false"]]
    cmd += ["--methods=fb,penalty,augmented_lagrangian"]  # fb first: the tie margin reads its c
    if nproc > 1:
        cmd = [MPIRUN, "-n", str(nproc), *cmd]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    subprocess.run(cmd, check=True, cwd=ROOT, timeout=300, env=env)
    return dict(np.load(out))


@pytest.mark.mpi
@pytest.mark.parametrize("name", list(SCENES))
def test_two_bodies_serial_equals_two_ranks(tmp_path, name) -> None:
    one, two = _bodies_run(tmp_path, 1, name), _bodies_run(tmp_path, 2, name)
    for method in ("penalty", "augmented_lagrangian"):
        s, p = one[f"{method}/info"], two[f"{method}/info"]
        assert s[0] == p[0] == 1 and s[2] == p[2]  # converged, the same contact nodes
        assert p[3] == pytest.approx(s[3], rel=1e-8)  # contact force
        assert s[4] < 1e-10 and p[4] < 1e-10  # action = reaction
        assert np.allclose(one[f"{method}/X"], two[f"{method}/X"], atol=1e-12)
        u, u2 = one[f"{method}/u"], two[f"{method}/u"]
        assert np.max(np.abs(u - u2)) <= 1e-8 * np.max(np.abs(u))
        lam, lam2 = one[f"{method}/lambda"], two[f"{method}/lambda"]
        assert np.max(np.abs(lam - lam2)) <= 1e-8 * np.max(np.abs(lam))


def cattaneo(method: str):
    scene = contact.load_scene(
        CATTANEO, ["mesh.h_contact=0.02", "output.verbose=false", f"solver.method={method}"]
    )
    return run_load_path(scene, verbose=False, keep_all=True)


@pytest.fixture(scope="module")
def cattaneo_min():
    return cattaneo("min")


@pytest.mark.parametrize("method", ["penalty", "augmented_lagrangian"])
def test_cattaneo_mindlin_with_coulomb(cattaneo_min, method) -> None:
    """Coulomb F = 0.3 through the mortar gap, P then Q: at Q/(F P) = 0.25, 0.5, 0.75 the
    stick zone c/a within 3 % and q(x) within 10 % (5 % at 0.5, 0.75) in L² of the
    Cattaneo–Mindlin solution, as min's on the same 17k-DoF mesh (test_bodies.py), and the
    tangential tractions of the last step equal min's to O(1/ε₀) (penalty) or Uzawa's
    tolerance."""
    runs = {"min": cattaneo_min, method: cattaneo(method)}
    steps = runs[method].steps
    assert all(s.result.converged for s in steps)
    values = [compare(s.posed, s.result).values for s in steps]
    assert abs(values[0]["Q_over_FP"]) < 1e-3
    assert np.allclose([v["Q_over_FP"] for v in values[1:]], [0.25, 0.5, 0.75], atol=0.005)
    assert all(abs(v["c_error"]) < 0.03 for v in values[1:])
    q = [v["q_error"] for v in values[1:]]
    assert q[0] < 0.10 and max(q[1:]) < 0.05
    lam_t = steps[-1].result.friction["lambda_t"]
    ref = runs["min"].steps[-1].result.friction["lambda_t"]
    tol = 1e-2 if method == "penalty" else 1e-6
    assert np.max(np.abs(lam_t - ref)) <= tol * np.max(np.abs(ref))


def test_tresca_through_the_mortar_gap_agrees_with_min() -> None:
    """Tresca (threshold 1) on the Cattaneo scene's interface, coarse: the law holds at every
    slave node, in contact or not, and the largest tangential traction of the last step
    reaches the threshold; the tractions equal min's to O(1/ε₀) (penalty, measured 5.4e-4 of
    the largest) or Uzawa's tolerance (3.5e-9), with the same status at every slave node."""
    runs = {}
    for m in ("min", "penalty", "augmented_lagrangian"):
        scene = contact.load_scene(
            CATTANEO,
            [
                "mesh.h_contact=0.08",
                "output.verbose=false",
                "reference=null",
                "friction={law: tresca, threshold: '1.0'}",
                f"solver.method={m}",
            ],
        )
        path = run_load_path(scene, verbose=False)
        assert path.converged, m
        runs[m] = path.steps[-1].result.friction
    ref = runs["min"]
    assert np.max(np.abs(ref["lambda_t"])) == pytest.approx(1.0, rel=1e-8)
    for m, tol in (("penalty", 1e-2), ("augmented_lagrangian", 1e-6)):
        assert np.array_equal(runs[m]["status"], ref["status"]), m
        gap = np.max(np.abs(runs[m]["lambda_t"] - ref["lambda_t"]))
        assert gap <= tol * np.max(np.abs(ref["lambda_t"])), (m, gap)
