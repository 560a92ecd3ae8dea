"""Friction (docs/theory.md §1.4, issue 12): the tangential law and its generalized Jacobian, the
block Jacobian H = B K + D of a frictional scene, full sliding of a pulled block (Tresca and
Coulomb force laws to round-off), Coulomb by full Newton against the Tresca fixed point,
F = 0 against the frictionless Hertz solutions, and one-line errors for bad friction input."""

import dataclasses
from pathlib import Path

import contact
from contact.setup.build import build_problem
from contact.solvers.friction import FrictionalComplementarity, tangential_law

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

#: a block [−1, 1] × [0, 0.5] pressed onto the plane y = 0 (top moved by (0.05, −0.01)):
#: dragged far beyond sliding for the friction coefficients and thresholds used below
BLOCK = {
    "name": "block",
    "mesh": {"type": "rectangle", "corners": [[-1, 0], [1, 0.5]], "cells": [40, 10]},
    "boundaries": {
        "bottom": {"role": "contact", "where": "y < 1e-10"},
        "top": {"role": "dirichlet", "where": "y > 0.5 - 1e-10"},
    },
    "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
    "obstacle": {"type": "plane", "point": [0, 0], "normal": [0, 1]},
    "data": {"u_D": ["0.05", "-0.01"]},
    "output": {"verbose": False},
}


def block(*overrides: str) -> contact.Scene:
    return contact.load_scene(BLOCK, list(overrides))


def coulomb(F: float) -> list[str]:
    return ["friction.law=coulomb", f"friction.coefficient={F}"]


def clear_of_kinks(f: dict, rtol: float = 1e-6) -> np.ndarray:
    """The contact nodes of ``Result.friction`` ``f`` whose status rounding cannot tip: not
    on the normal kink (λ_n ≈ 0 with gap ≈ 0) nor on the stick/slip one (|λ_t| ≈ ρ with
    slip ≈ 0), each to ``rtol`` of the largest value."""

    def big(v):
        v = np.abs(v)
        return v > rtol * max(np.max(v, initial=0.0), 1e-300)

    t_norm, slip = np.linalg.norm(f["lambda_t"], axis=1), np.linalg.norm(f["slip"], axis=1)
    normal = big(f["lambda_n"]) | big(f["gap"])
    tangential = (
        (f["rho"] - t_norm > rtol * np.max(f["rho"], initial=0.0)) | big(slip) | (f["rho"] == 0)
    )
    return normal & tangential


# ------------------------------------------------------------------- the law, pointwise
def _fd(fun, x, h=1e-7):
    """Central differences of fun (n, k) → (n, m) along each of the k inputs: (n, m, k)."""
    cols = []
    for j in range(x.shape[1]):
        e = np.zeros_like(x)
        e[:, j] = h
        cols.append((fun(x + e) - fun(x - e)) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("m", [1, 2])
def test_projection_law_jacobian_is_the_derivative(m):
    """Stick and slip nodes (no kinks): J_μ, J_s, J_ρ are the derivatives of
    C = μ − P_B(ρ)(μ + c_t s), by central differences."""
    rng = np.random.default_rng(0)
    n = 200
    mu, s = rng.normal(size=(n, m)), rng.normal(size=(n, m)) * 0.5
    c_t, rho = rng.uniform(0.5, 2.0, n), rng.uniform(0.2, 3.0, n)
    free = np.ones((n, m), bool)
    law = tangential_law(mu, s, rho, c_t, free)
    z = np.linalg.norm(mu + c_t[:, None] * s, axis=1)
    ok = np.abs(z - rho) > 1e-3  # away from the stick/slip kink
    assert ok.sum() > 150 and 20 < law.stick[ok].sum() < ok.sum() - 20

    def C_of_mu(m_):
        return tangential_law(m_, s, rho, c_t, free).C

    def C_of_s(s_):
        return tangential_law(mu, s_, rho, c_t, free).C

    def C_of_rho(r_):
        return tangential_law(mu, s, r_[:, 0], c_t, free).C

    assert np.allclose(law.J_mu[ok], _fd(C_of_mu, mu)[ok], atol=1e-6)
    assert np.allclose(law.J_s[ok], _fd(C_of_s, s)[ok], atol=1e-6)
    assert np.allclose(law.J_rho[ok], _fd(C_of_rho, rho[:, None])[ok, :, 0], atol=1e-6)


def test_hsw_law_jacobian_is_the_scaled_derivative_of_the_max_form():
    """Inside the ball (|μ_t| ≤ ρ, where HSW's modification is void) the hsw element is
    (1/max(ρ, |z|)) ∂[max(ρ, |z|) μ_t − ρ z], and its row value is the projection form's."""
    rng = np.random.default_rng(1)
    n, m = 200, 2
    rho = rng.uniform(0.5, 2.0, n)
    mu = rng.normal(size=(n, m))
    mu *= (rho * rng.uniform(0.0, 0.95, n) / np.linalg.norm(mu, axis=1))[:, None]
    s, c_t, free = rng.normal(size=(n, m)), rng.uniform(0.5, 2.0, n), np.ones((n, m), bool)
    law = tangential_law(mu, s, rho, c_t, free, "hsw")
    assert np.array_equal(law.C, tangential_law(mu, s, rho, c_t, free).C)
    z = mu + c_t[:, None] * s
    scale = np.maximum(rho, np.linalg.norm(z, axis=1))
    ok = np.abs(np.linalg.norm(z, axis=1) - rho) > 1e-3

    def hsw(mu_, s_):
        z_ = mu_ + c_t[:, None] * s_
        return np.maximum(rho, np.linalg.norm(z_, axis=1))[:, None] * mu_ - rho[:, None] * z_

    assert np.allclose(
        law.J_mu[ok], (_fd(lambda v: hsw(v, s), mu) / scale[:, None, None])[ok], atol=1e-6
    )
    assert np.allclose(
        law.J_s[ok], (_fd(lambda v: hsw(mu, v), s) / scale[:, None, None])[ok], atol=1e-6
    )


def test_fixed_components_and_zero_bound():
    """A fixed component is absent from |z| and from the blocks; ρ = 0 gives the free row
    (C = μ_t, J_μ = I), where HSW's unscaled max form would vanish identically."""
    mu, s = np.array([[0.3, 5.0], [0.2, -0.1]]), np.array([[0.1, 7.0], [0.4, 0.3]])
    free = np.array([[True, False], [True, True]])
    law = tangential_law(mu, s, np.array([1.0, 0.0]), np.ones(2), free)
    assert (
        law.stick[0]
        and law.C[0, 1] == 0
        and np.all(law.J_mu[0, :, 1] == 0)
        and np.all(law.J_s[0, 1] == 0)
    )
    assert np.allclose(law.C[1], mu[1]) and np.allclose(law.J_mu[1], np.eye(2)) and not law.stick[1]


def with_form(fs, form: str):
    """The friction set with another tangential NCP (its FrictionOptions copied)."""
    return dataclasses.replace(fs, options=fs.options.model_copy(update={"form": form}))


def test_block_jacobian_is_the_directional_derivative_of_phi():
    """H = B K + D of a Coulomb scene (normal fb, projection form) against central
    differences of Φ at a point with stick and slip nodes.  The point is the
    solution (found with hsw: the same Φ, and the form that converges from any start) plus
    noise; a node whose state (separated / stick / slip) differs at x − hv, x or x + hv sits
    on a kink of Φ there, and its rows are left out (none or a few of ~80 nodes)."""
    from petsc4py import PETSc

    scene = block(*coulomb(0.3), 'data.u_D=["0.004", "-0.01"]', "friction.form=projection")
    problem = build_problem(scene)
    problem.friction = with_form(problem.friction, "hsw")
    r = contact.solve(scene, problem=problem)
    problem.friction = with_form(problem.friction, "projection")
    assert r.converged and {1, 2} <= set(r.friction["status"].tolist())
    cp = FrictionalComplementarity(problem)
    x = problem.b.duplicate()
    problem.to_unknowns(r.u_h.x.petsc_vec, x)
    rng = np.random.default_rng(2)
    x.array[:] += 1e-4 * rng.normal(size=x.getLocalSize())
    v = x.duplicate()
    v.array[:] = rng.normal(size=x.getLocalSize())
    H = cp.matrix()
    cp.block_jacobian(x, H, "fb", 0.5)
    Hv, fp, fm = x.duplicate(), x.duplicate(), x.duplicate()
    H.mult(v, Hv)
    h = 1e-7
    states = [cp.status(x)]
    for sign, out in ((1, fp), (-1, fm)):
        xs = x.copy()
        xs.axpy(sign * h, v)
        cp.phi(xs, out, "fb", 0.5)
        states.append(cp.status(xs))
    assert {1, 2} <= set(states[0].tolist())
    smooth = (states[0] == states[1]) & (states[0] == states[2])
    assert smooth.sum() >= len(smooth) - 3
    rows = np.ones(x.getLocalSize(), bool)
    rows[cp.dofs[~smooth]] = False
    rows[cp.fs.tangent[~smooth].ravel()] = False
    fd = (fp.array - fm.array) / (2 * h)
    assert np.max(np.abs(fd - Hv.array)[rows]) <= 1e-5 * np.max(np.abs(Hv.array))
    assert H.getInfo()["nz_used"] == problem.K.getInfo()["nz_used"]  # the pattern of K
    for obj in (H, Hv, fp, fm, x, v):
        obj.destroy()
    assert isinstance(PETSc.ScalarType(0), np.floating)


# ------------------------------------------------------------------- full sliding
@pytest.mark.parametrize(
    "method,form", [("fb", "projection"), ("min", "projection"), ("min", "hsw")]
)
def test_pulled_block_tresca_force_is_threshold_times_length(method, form):
    scene = block("friction.law=tresca", "friction.threshold=0.01", f"friction.form={form}")
    r = contact.solve(scene, method=method)
    f = r.friction
    assert r.converged and r.iterations <= 10  # a bound: 2–8 steps here, 10 catches a cycle
    # every contact node slips
    assert np.all(f["status"][f["status"] > 0] == 2)
    Ft = scene.comm.allreduce(float(np.sum(f["w"] * f["lambda_t"][:, 0])))
    assert abs(Ft + 0.01 * 2.0) <= 1e-12  # −s·|Γ_C|: opposes +x
    assert np.all(f["slip"][:, 0] > 0)


@pytest.mark.parametrize(
    "method,form",
    [("fb", "projection"), ("min", "projection"), ("fb", "hsw"), ("blend", "projection")],
)
def test_pulled_block_coulomb_force_is_F_times_normal_force(method, form):
    scene = block(*coulomb(0.3), f"friction.form={form}")
    r = contact.solve(scene, method=method)
    f = r.friction
    assert r.converged and r.iterations <= 10  # a bound: 4–8 steps here, 10 catches a cycle
    Ft = scene.comm.allreduce(float(np.sum(f["w"] * f["lambda_t"][:, 0])))
    Fn = scene.comm.allreduce(float(np.sum(f["w"] * f["lambda_n"])))
    assert Fn < 0 and abs(Ft - 0.3 * Fn) <= 1e-8 * abs(Fn)
    # every node in clear contact slides; the leading edge lifts off with λ_n = 0 up to
    # round-off (−7e-17 or −0 depending on the method and the CPU): that tie is not asserted
    pressed = f["lambda_n"] < -1e-8 * np.max(np.abs(f["lambda_n"]))
    assert pressed.sum() >= 35 and np.all(f["status"][pressed] == 2)


# ------------------------------------------------------------------- Coulomb: SSN = fixed point
def test_coulomb_newton_equals_fixed_point_2d():
    """Partial slip (a small drag): full semismooth Newton and the sequence of Tresca problems."""
    base = [*coulomb(0.3), 'data.u_D=["0.004", "-0.01"]']
    ssn = contact.solve(block(*base))
    fp = contact.solve(block(*base, "friction.coulomb=fixed_point"))
    # a lower bound: the pressure moves with the slip, so the fixed point takes several Tresca
    # solves
    assert ssn.converged and fp.converged and fp.friction["fixed_point_iterations"] > 2
    scale = np.max(np.abs(ssn.u_h.x.array))
    assert np.max(np.abs(ssn.u_h.x.array - fp.u_h.x.array)) <= 1e-8 * scale
    lam = np.max(np.abs(ssn.friction["lambda_t"]))
    assert np.max(np.abs(ssn.friction["lambda_t"] - fp.friction["lambda_t"])) <= 1e-8 * lam
    f, clear = ssn.friction, clear_of_kinks(ssn.friction)
    assert clear.sum() >= 0.9 * len(clear) and np.array_equal(
        f["status"][clear], fp.friction["status"][clear]
    )
    assert {1, 2} <= set(f["status"].tolist())  # stick and slip


#: a box [−½, ½]² × [0, ¼] pressed onto the plane z = 0 (top moved by (0.001, 0.0005, −0.005)):
#: partial slip for F = 0.3
BOX = {
    "name": "box",
    "mesh": {"type": "box", "corners": [[-0.5, -0.5, 0], [0.5, 0.5, 0.25]], "cells": [8, 8, 4]},
    "boundaries": {
        "bottom": {"role": "contact", "where": "z < 1e-10"},
        "top": {"role": "dirichlet", "where": "z > 0.25 - 1e-10"},
    },
    "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
    "obstacle": {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]},
    "data": {"u_D": ["0.001", "0.0005", "-0.005"]},
    "friction": {"law": "coulomb", "coefficient": 0.3},
    "output": {"verbose": False},
}


def test_coulomb_newton_equals_fixed_point_3d():
    """3D partial slip (2 tangential unknowns per node): full Newton (hsw) and the fixed point
    agree; every slipping node is on the cone |λ_t| = F|λ_n|, every sticking node inside."""
    ssn = contact.solve(contact.load_scene(BOX))
    fp = contact.solve(contact.load_scene(BOX, ["friction.coulomb=fixed_point"]))
    # a bound (a cycle would hit it)
    assert ssn.converged and fp.converged and ssn.iterations <= 10
    u = ssn.u_h.x.array
    assert np.max(np.abs(u - fp.u_h.x.array)) <= 1e-8 * np.max(np.abs(u))
    f = ssn.friction
    status, cone = f["status"], 0.3 * np.abs(f["lambda_n"])
    norm_t = np.linalg.norm(f["lambda_t"], axis=1)
    assert (status == 1).sum() > 20 and (status == 2).sum() > 20
    assert np.allclose(norm_t[status == 2], cone[status == 2], rtol=1e-9)
    assert np.all(norm_t[status == 1] < cone[status == 1])
    # opposes the slip
    assert np.all(np.einsum("ij,ij->i", f["lambda_t"], f["slip"])[status == 2] < 0)


# ------------------------------------------------------------------- F = 0 is frictionless
HERTZ_SMALL = {
    "hertz_2d": ["mesh.h=0.2", "mesh.h_contact=0.02", "mesh.zone=0.2"],
    "hertz_3d": ["mesh.h=0.3", "mesh.h_contact=0.03", "mesh.zone=0.2"],
}


@pytest.mark.parametrize("name", sorted(HERTZ_SMALL))
def test_zero_friction_reproduces_frictionless_hertz(name):
    sets = HERTZ_SMALL[name] + [
        "output.verbose=false",
        "solver.petsc_options={ksp_type: preonly, pc_type: lu, pc_factor_mat_solver_type: mumps}",
    ]
    path = ROOT / "configs" / f"{name}.yaml"
    ref = contact.solve(contact.load_scene(path, sets))
    r = contact.solve(contact.load_scene(path, sets + coulomb(0.0)))
    assert ref.converged and r.converged
    assert np.max(np.abs(r.u_h.x.array - ref.u_h.x.array)) <= 1e-10 * np.max(
        np.abs(ref.u_h.x.array)
    )
    assert np.max(np.abs(r.friction["lambda_t"])) <= 1e-10 * np.max(np.abs(r.friction["lambda_n"]))


# ------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "overrides,message",
    [
        (["friction.law=tresca"], "friction.threshold: required for friction law tresca"),
        (["friction.law=coulomb"], "friction.coefficient: required for friction law coulomb"),
        (
            [*coulomb(0.3), "friction.threshold=1"],
            "friction.threshold: not used by friction law coulomb",
        ),
        (
            ["friction.law=tresca", "friction.threshold=1", "friction.coefficient=1"],
            "friction.coefficient: not used by friction law tresca",
        ),
        ([*coulomb(-0.1)], "friction.coefficient: must be >= 0"),
        (
            [*coulomb(0.3), "solver.method=vinewtonrsls"],
            "solver.method: vinewtonrsls cannot solve frictional contact",
        ),
        (
            [*coulomb(0.3), "friction.form=max"],
            "friction.form: 'max' is not one of projection, hsw",
        ),
        (["constants.t=1"], "constants.t: is not a usable constant name"),
        (
            ["boundaries.bottom.where=y < 1e-10*t"],
            "boundaries.bottom.where: the pseudo-time t is only for data",
        ),
        (["load.steps=2", "load.times=[1]"], "load: give exactly one of 'steps' or 'times'"),
        (
            ["load.times=[0.5, 0.2]"],
            "load.times: the pseudo-times must be > 0 and strictly increasing",
        ),
    ],
)
def test_bad_friction_input(overrides, message):
    with pytest.raises(
        contact.ConfigError,
        match=message.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)"),
    ):
        block(*overrides)


def test_friction_needs_elasticity_and_a_threshold_that_is_not_negative():
    with pytest.raises(
        contact.ConfigError, match="friction.law: tresca friction needs model type elasticity"
    ):
        contact.load_scene(
            ROOT / "configs" / "signorini_square.yaml",
            ["friction.law=tresca", "friction.threshold=1"],
        )
    with pytest.raises(
        contact.ConfigError, match="friction.threshold: negative or undefined at 21 contact node"
    ):
        build_problem(block("friction.law=tresca", "friction.threshold=x - 0.01"))


def test_drag_across_a_symmetry_plane_is_refused():
    sets = HERTZ_SMALL["hertz_2d"] + coulomb(0.3) + ['data.u_D=["0.01", "-delta"]']
    with pytest.raises(
        contact.ConfigError, match=r"data.u_D\[0\]: moves nodes of a symmetry plane across it"
    ):
        build_problem(contact.load_scene(ROOT / "configs" / "hertz_2d.yaml", sets))


def test_curved_obstacle_uses_the_rotated_frames():
    """A rigid circle indenting a block (rotated (n, t) unknowns per node): the frames are
    orthonormal to the nodal normals, Newton = fixed point, slipping nodes are on the cone."""
    sets = [
        "mesh.cells=[40,20]",
        *coulomb(0.3),
        "output.verbose=false",
        'data.u_D=["0.002", "delta"]',
    ]
    path = ROOT / "configs" / "indentation_2d.yaml"
    problem = build_problem(contact.load_scene(path, sets))
    frames, normals = problem.friction.frames, problem.data.normals
    assert np.max(np.abs(np.einsum("ni,nim->nm", normals, frames))) < 1e-14
    assert np.allclose(np.linalg.norm(frames, axis=1), 1.0)
    ssn = contact.solve(contact.load_scene(path, sets))
    fp = contact.solve(contact.load_scene(path, sets + ["friction.coulomb=fixed_point"]))
    assert ssn.converged and fp.converged
    assert np.max(np.abs(ssn.u_h.x.array - fp.u_h.x.array)) <= 1e-8 * np.max(
        np.abs(ssn.u_h.x.array)
    )
    f = ssn.friction
    slip = f["status"] == 2
    assert slip.sum() >= 2 and (f["status"] == 1).sum() >= 2
    assert np.allclose(np.abs(f["lambda_t"][slip, 0]), 0.3 * np.abs(f["lambda_n"][slip]), rtol=1e-9)
