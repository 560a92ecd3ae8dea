"""The adaptive loop and grid sequencing of hyperelastic bodies in contact through mortar
pairs (re-coupled on the current configuration, contact/drivers/recouple.py).

Each level of the adaptive loop solves the coupling's fixed point on its mesh (the previous
level's solution prolonged: the first coupling is that of its configuration); the residual
estimator's interface terms compare the nominal traction P(u_h)N with the pressures per
current area times da/dA along the current normals.  Checked on two neo-Hookean cylinders
(configs/two_body_hertz_2d.yaml made hyperelastic): at a small load the estimator and the
meshes are the linear elastic ones; at δ = 0.1 R_c Dörfler's force converges with the levels
and the interface forces balance; the finite-strain patch test (a homogeneous state the mesh
represents exactly) has η at round-off, where the reference configuration's normal and
area would leave the consistency term at the stretch's size; the CLI's adaptive load path
gives the same meshes, η and forces serially and on 2 ranks.  Grid sequencing: each coarse
level its own fixed point of couplings; the sequenced solve reaches the cold solve's force
to 1e-8 in fewer fine Newton steps; ``auto`` does not sequence pairs.  With Coulomb friction
between sliding bodies η falls and the friction terms stay at the solver's tolerance."""

from __future__ import annotations

import csv
import warnings

import contact
from contact.base.errors import ContactWarning

import numpy as np
import pytest
import ufl
from clirun import ROOT
from clirun import contact as cli
from dolfinx import fem
from mpi4py import MPI

HERTZ_2D = ROOT / "configs" / "two_body_hertz_2d.yaml"
PATCH_2D = ROOT / "configs" / "hyperelastic_two_body_patch_2d.yaml"
NEO_HOOKEAN = ["model.type=hyperelastic", "model.law=neo_hookean"]


def cylinders(*sets: str) -> contact.Scene:
    """The two cylinders (R_c = 8) with ``sets``, quiet."""
    return contact.load_scene(HERTZ_2D, ["output.verbose=false", *sets])


def quiet(run, scene: contact.Scene):
    """``run(scene)`` (contact.adapt or contact.solve), the half-disks' untagged arcs away
    from the contact (σn = 0, as shipped) not warned about."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "boundary: .* exterior facet", ContactWarning)
        return run(scene, verbose=False)


def adapt(scene: contact.Scene):
    return quiet(contact.adapt, scene)


def test_small_load_estimator_and_meshes_are_the_linear_elastic_ones():
    """δ = 0.001 R_c, 3 Dörfler levels: neo-Hookean and linear elastic cylinders have the same
    DoFs per level to 0.2 % (the marked sets differ by a few cells where indicators tie), η
    and the contact force to 1 %, each interface term to 10 %."""
    runs = [
        adapt(cylinders(*m, "constants.delta=0.008", "adapt.max_levels=3"))
        for m in (NEO_HOOKEAN, [])
    ]
    finite, linear = ([lv for lv in run.levels] for run in runs)
    assert len(finite) == len(linear) == 3
    for a, b in zip(finite, linear):
        assert a.result.converged and b.result.converged
        assert abs(a.result.dofs - b.result.dofs) <= 2e-3 * b.result.dofs
        assert a.estimate.eta == pytest.approx(b.estimate.eta, rel=1e-2)
        assert a.result.contact_force == pytest.approx(b.result.contact_force, rel=1e-2)
        for term in ("consistency", "consistency_master", "tangential"):
            assert a.estimate.terms[term] == pytest.approx(b.estimate.terms[term], rel=0.1)
    assert all(len(lv.result.couplings) >= 2 for lv in finite)  # re-coupled on every level


def test_dorfler_force_converges_for_two_neo_hookean_cylinders():
    """δ = 0.1 R_c (a ≈ 0.3 R_c) from the default mesh, 5 Dörfler levels: η falls on every
    level; the force falls monotonically and its changes contract (each ≤ 0.7× the one before;
    measured −0.31, −0.19, −0.11, −0.05), the last below 0.1 %; on every level the fixed point
    of couplings converged and the slave and master surface forces cancel to 1e-8."""
    run = adapt(cylinders(*NEO_HOOKEAN, "constants.delta=0.8", "adapt.max_levels=5"))
    levels = run.levels
    assert len(levels) == 5 and all(lv.result.converged for lv in levels)
    etas = [lv.estimate.eta for lv in levels]
    assert all(b < a for a, b in zip(etas, etas[1:]))
    forces = np.array([lv.result.contact_force for lv in levels])
    changes = np.diff(forces)
    assert np.all(changes < 0)
    assert np.all(np.abs(changes[1:]) <= 0.7 * np.abs(changes[:-1]))
    assert abs(changes[-1]) < 1e-3 * forces[-1]
    for lv in levels:
        slave, master = lv.result.interface_forces
        assert np.linalg.norm(slave + master) <= 1e-8 * np.linalg.norm(slave)


def test_adapt_with_coulomb_between_sliding_bodies():
    """configs/hyperelastic_two_body_drag_2d.yaml (a neo-Hookean block pressed and dragged
    over another, Coulomb F = 0.3) in 5 steps, 3 Dörfler levels at the last (full slip): η
    falls; the friction bound's term vanishes (≤ 1e-8 η²) and the slip's stays at the
    solver's tolerance (≤ 1e-3 η²; measured 6e-8 … 1.5e-7 against η² ≥ 3e-4); the slave and
    master surface forces cancel to 1e-8 on every level."""
    drag = ROOT / "configs" / "hyperelastic_two_body_drag_2d.yaml"
    scene = contact.load_scene(
        drag,
        ["output.verbose=false", "load.steps=5", "adapt.strategy=dorfler", "adapt.max_levels=3"],
    )
    path = contact.run_load_path(scene, verbose=False)
    assert path.converged
    levels = path.steps[-1].levels
    etas = [lv.estimate.eta for lv in levels]
    assert len(levels) == 3 and all(b < a for a, b in zip(etas, etas[1:]))
    for lv in levels:
        terms, eta2 = lv.estimate.terms, lv.estimate.eta**2
        assert terms["friction_bound"] <= 1e-8 * eta2
        assert terms["slip"] <= 1e-3 * eta2
        slave, master = lv.result.interface_forces
        assert np.linalg.norm(slave + master) <= 1e-8 * np.linalg.norm(slave)


def test_patch_estimate_vanishes_on_the_current_configuration():
    """The finite-strain patch test (two neo-Hookean blocks compressed 17 %, non-matching):
    the discrete solution is the exact homogeneous state, so every term of η is at round-off
    (η ≤ 1e-12 · ‖P N‖ h^{1/2} on the top); taken with the reference normal and area (λ_h per
    reference area) the slave's consistency term would be ≥ 1e-6: the terms use da/dA."""
    scene = contact.load_scene(PATCH_2D, ["output.verbose=false", "load=none"])
    with warnings.catch_warnings():  # the blocks' free right sides: σn = 0 (as shipped)
        warnings.filterwarnings("ignore", "boundary: .* exterior facet", ContactWarning)
        result = contact.solve(scene, verbose=False)
        est = contact.estimate(scene, result)
    assert result.converged
    assert est.eta <= 1e-12
    problem = result.problem
    (pair,) = [c for c in problem.contacts if isinstance(c, contact.MortarPair)]
    u_h, lam = result.u_h, result.lmbda_h
    msh = u_h.function_space.mesh
    n = ufl.FacetNormal(msh)
    T = ufl.dot(problem.physics.flux(u_h), n)  # P(u_h) N
    ds = problem.physics.boundary.measure(msh)
    h_E = ufl.FacetArea(msh)
    reference = sum(h_E * (lam - ufl.dot(T, n)) ** 2 * ds(i) for i in pair.ids)
    value = msh.comm.allreduce(fem.assemble_scalar(fem.form(reference)), op=MPI.SUM)
    assert value >= 1e-6


def test_grid_sequencing_reaches_the_cold_force_in_fewer_fine_newton_steps():
    """δ = 0.1 R_c, ``solver.sequence: 2``: two coarser half-disk meshes (772 and 1 720
    DoFs), each solved to its own fixed point of couplings; the fine fixed point starts on
    the configuration of their solution: the cold solve's force to 1e-8 in fewer fine Newton
    steps (measured 13 → 10) and no more couplings.  ``auto`` does not sequence pairs."""
    cold, seq = (
        quiet(
            contact.solve,
            cylinders(*NEO_HOOKEAN, "adapt=none", "constants.delta=0.8", f"solver.sequence={s}"),
        )
        for s in ("off", 2)
    )
    assert cold.converged and seq.converged and not cold.sequence
    assert [lv.dofs for lv in seq.sequence] == [772, 1720]
    assert all(lv.converged for lv in seq.sequence)
    assert seq.contact_force == pytest.approx(cold.contact_force, rel=1e-8)
    assert seq.iterations < cold.iterations
    assert len(seq.couplings) <= len(cold.couplings)
    auto = cylinders(*NEO_HOOKEAN, "adapt=none")
    assert auto.config.solver.sequence == "off"


def _read(path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.mpi
def test_cli_adaptive_load_path_serial_equals_two_ranks(tmp_path):
    """The CLI on the cylinders at finite strain (h_contact = 0.2, δ = 0.1 R_c in 2 steps,
    3 Dörfler levels at the last), serially and on 2 ranks: exit 0, η falls with the levels;
    the same DoFs per level, η and forces (steps.csv) to 1e-8."""
    args = [
        "run",
        str(HERTZ_2D),
        "-q",
        *(a for s in NEO_HOOKEAN for a in ("--set", s)),
        *("--set", "constants.delta=0.8", "--set", "mesh.h_contact=0.2"),
        *("--set", 'data.u_D=["0", "-delta * t * (y > 0)"]', "--set", "load.steps=2"),
        *("--set", "adapt.max_levels=3", "--set", "output.png=false"),
    ]
    runs = {}
    for ranks in (0, 2):
        out = tmp_path / f"np{ranks}"
        proc = cli(tmp_path, *args, "-o", str(out), ranks=ranks)
        assert proc.returncode == 0, proc.stderr[-2000:]
        levels = _read(out / "convergence.csv")
        etas = [float(r["eta"]) for r in levels]
        assert len(levels) == 3 and all(b < a for a, b in zip(etas, etas[1:]))
        steps = _read(out / "steps.csv")
        forces = [float(r["contact_force"]) for r in steps]
        runs[ranks] = ([int(r["dofs"]) for r in levels], etas, forces)
    (d0, e0, f0), (d2, e2, f2) = runs[0], runs[2]
    assert d0 == d2
    np.testing.assert_allclose(e2, e0, rtol=1e-8)
    np.testing.assert_allclose(f2, f0, rtol=1e-8)
