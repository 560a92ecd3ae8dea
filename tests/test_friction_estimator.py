"""The manufactured Tresca solution (configs/friction_tresca_manufactured.yaml, issue 12):
its data are consistent with the exact solution, the discrete stick/slip status is exact away
from the transition, the energy error is O(h) under uniform refinement, Dörfler refinement
converges at rate ≥ 0.45 in N with the Hild–Lleras friction estimator, whose effectivity
stays in a band of width ≤ 2; and a frictionless scene keeps today's estimator."""

from pathlib import Path

import contact
from contact.adaptivity.energy_error import solution_error
from contact.base import expressions
from contact.models.elasticity import stress
from contact.models.physics import lame
from contact.post.contact_table import contact_table, tangent_2d
from contact.post.traction_curves import exact_tractions
from contact.setup.posed import posed_of

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "configs" / "friction_tresca_manufactured.yaml"
QUIET = ["output.verbose=false"]


def _ufl_vector(texts, scene):
    return ufl.as_vector([expressions.to_ufl(t, scene.mesh, scene.config.constants) for t in texts])


def test_manufactured_data_are_those_of_the_exact_solution():
    """f = −div σ(u), t = σ(u)n on the sides, u_D = u, the Lamé constants those of E, ν; on
    Γ_C u_y = 0, σ_yy < 0, σ_xy = μα and the threshold is μα (slip side) / > μα (stick side)."""
    scene = contact.load_scene(SCENE, QUIET + ["mesh.cells=[16,16]"])
    c, d = scene.config.constants, scene.config.data
    mu, lmbda = lame(1.0, 0.3)
    assert np.isclose(c["mu"], mu, rtol=1e-15) and np.isclose(c["lam"], lmbda, rtol=1e-15)
    assert d.u_D == d.exact
    u, f, t = (_ufl_vector(getattr(d, k), scene) for k in ("exact", "f", "t"))
    sigma = stress(u, mu, lmbda)
    dx = ufl.Measure("dx", domain=scene.mesh, metadata={"quadrature_degree": 10})
    n = ufl.FacetNormal(scene.mesh)
    ds = ufl.Measure(
        "ds",
        domain=scene.mesh,
        subdomain_data=scene.boundary.tags,
        metadata={"quadrature_degree": 10},
    )
    sides, floor = scene.boundary.ids["sides"], scene.boundary.ids["floor"]

    def integral(expr, measure):
        return scene.comm.allreduce(fem.assemble_scalar(fem.form(expr * measure)), op=MPI.SUM)

    r = f + ufl.div(sigma)
    assert integral(ufl.inner(r, r), dx) < 1e-20 * integral(ufl.inner(f, f), dx)
    e = t - ufl.dot(sigma, n)
    assert integral(ufl.inner(e, e), ds(sides)) < 1e-20 * integral(ufl.inner(t, t), ds(sides))
    x = ufl.SpatialCoordinate(scene.mesh)
    rho = expressions.to_ufl(scene.config.friction.threshold, scene.mesh, c)
    assert integral(u[1] ** 2, ds(floor)) < 1e-28
    assert integral((sigma[0, 1] - mu * c["alpha"]) ** 2, ds(floor)) < 1e-28
    slip_side = ufl.conditional(ufl.gt(x[0], c["x0"]), 1.0, 0.0)
    assert integral(slip_side * (rho - mu * c["alpha"]) ** 2, ds(floor)) < 1e-28
    margin = integral((1 - slip_side) * (rho - mu * c["alpha"]), ds(floor))
    assert margin == pytest.approx(mu * c["alpha"] * 0.25, rel=1e-12)  # ∫_0^½ 2μα(½ − x) dx


def _status_exact(scene, result, distance):
    table = contact_table(posed_of(scene), result)
    if scene.comm.rank != 0:
        return True
    x, status = table["x"], table["status"]
    far = np.abs(x - 0.5) >= distance
    return bool(
        np.all(status[far & (x < 0.5)] == "stick")
        and np.all(status[far & (x > 0.5)] == "slip")
        and far.sum() >= 0.6 * len(x)
    )


def test_uniform_refinement_is_order_h_with_exact_stick_slip_zones():
    errors, dofs = [], []
    for n in (8, 16, 32, 64):
        scene = contact.load_scene(SCENE, QUIET + [f"mesh.cells=[{n},{n}]"])
        r = contact.solve(scene)
        assert r.converged
        assert _status_exact(scene, r, 0.1)
        errors.append(solution_error(r.problem, r))
        dofs.append(r.dofs)
    rates = -np.diff(np.log(errors)) / np.diff(np.log(dofs))
    assert np.all(rates > 0.48), rates  # O(h) = O(N^{-1/2})
    assert errors[-1] < 0.017
    # the nodal multipliers against the exact tractions (the reference curves of traction.png)
    table = contact_table(posed_of(scene), r)
    if scene.comm.rank == 0:
        (_, s, p_exact, _), (_, _, t_exact, _) = exact_tractions(
            posed_of(scene), table, tangent_2d(r)
        )
        # the arc length along y = 0
        assert np.allclose(s, table["x"]) and s[0] == pytest.approx(0.0)
        assert np.max(np.abs(p_exact + table["lambda_n"])) < 0.02 * np.max(p_exact)
        assert np.max(np.abs(t_exact - table["lambda_t"])) < 0.02 * np.max(np.abs(t_exact))
        assert np.allclose(t_exact, -0.5 * lame(1.0, 0.3)[0], rtol=1e-6)  # λ_t = −μα


def test_dorfler_adaptive_rate_and_effectivity_band():
    """Dörfler (θ = 0.5) from 8×8 to ~8000 DoFs: error ~ N^{-1/2} (fitted over the last five
    levels) and η / error within a band max/min ≤ 2 over the last five levels; the friction
    terms are computed (the slip term is not zero)."""
    scene = contact.load_scene(SCENE, QUIET)
    run = contact.adapt(scene, max_dofs=8000)
    rows = run.rows
    assert len(rows) >= 7 and all(lv.result.converged for lv in run.levels)
    last = rows[-5:]
    N = np.array([r["dofs"] for r in last], float)
    err = np.array([r["error"] for r in last], float)
    rate = -np.polyfit(np.log(N), np.log(err), 1)[0]
    assert rate >= 0.45, rate
    eff = np.array([r["effectivity"] for r in last], float)
    assert eff.max() / eff.min() <= 2.0 and eff.min() > 1.0
    assert {"eta2_tangential", "eta2_friction_bound", "eta2_slip"} <= set(rows[-1])
    assert rows[-1]["eta2_slip"] > 0
    lv = run.levels[-1]
    assert _status_exact(lv.scene, lv.result, 0.1)


def test_frictionless_estimator_unchanged_and_zero_friction_equal():
    """A frictionless elastic scene has today's terms (tangential = h_E‖σ_t(u_h)‖²); F = 0 gives
    the same η and terms, with zero friction-bound and slip terms."""
    sets = ["mesh.h=0.2", "mesh.h_contact=0.02", "mesh.zone=0.2"] + QUIET
    path = ROOT / "configs" / "hertz_2d.yaml"
    scene = contact.load_scene(path, sets)
    est = contact.estimate(scene, contact.solve(scene))
    assert set(est.terms) == {
        "volume",
        "jump",
        "neumann",
        "consistency",
        "tangential",
        "sign",
        "complementarity",
    }
    scene0 = contact.load_scene(path, sets + ["friction.law=coulomb", "friction.coefficient=0"])
    est0 = contact.estimate(scene0, contact.solve(scene0))
    assert (
        est0.terms["friction_bound"] < 1e-14 * est.eta**2
        and est0.terms["slip"] < 1e-14 * est.eta**2
    )
    for name, value in est.terms.items():
        assert est0.terms[name] == pytest.approx(value, rel=1e-8, abs=1e-14)
    assert est0.eta == pytest.approx(est.eta, rel=1e-10)
