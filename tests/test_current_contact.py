"""Contact on the current configuration (issue 31): a hyperelastic body against a rigid
circle or sphere, the gap g(X + u) nonlinear in u, the normal and frame followed at every
Newton iterate (contact/solvers/current.py).

Checked against: finite differences of Φ (the generalized Jacobian, curvature term
included, is the derivative where Φ is smooth); the plane path (a circle of radius R → ∞
tends to the plane, the difference ∝ 1/R); an independent solver of the same discrete
problem (a sequence of VI solves with the gap linearized at the last iterate, PETSc's
vinewtonrsls); frame invariance with large sliding (the body turned about the circle's
centre slides R θ along it and gives the rotated solution); the linear Hertz scene at small
indentation; Newton's superlinear rate."""

from __future__ import annotations

import contact
from contact import ConfigError
from contact.models.hyperelastic import linearized_problem
from contact.output.run_report import active_measure
from contact.post.resultants import contact_resultants, reaction_force
from contact.setup.build import build_problem
from contact.setup.posed import posed_of
from contact.solvers import owned_residual
from contact.solvers.current import CurrentComplementarity, nodal_geometry

import numpy as np
import pytest
from clirun import ROOT
from dolfinx import fem
from mpi4py import MPI
from test_hyperelastic import arch, superlinear_steps

E, NU = 1.0, 0.3


def indentation(
    dim: int = 2,
    delta: float = 0.05,
    cells: tuple = (12, 6),
    scale: float = 1.0,
    friction: dict | None = None,
    u_D: list | None = None,
    shift: float = 0.3,
) -> dict:
    """A block [−L, L]^(d−1) × [−L, 0] clamped at its bottom, indented at its top by a rigid
    circle / sphere of radius L/2 lowered by δ (and moved sideways by ``shift`` δ: the contact
    is not symmetric); ``scale`` = L."""
    L = scale
    lower = [-L] * dim
    upper = [L] * (dim - 1) + [0]
    last = "xyz"[dim - 1]
    centre = [f"{shift}*delta*t"] + ["0"] * (dim - 2) + [f"{0.5 * L} - delta*t"]
    cfg = {
        "name": "indentation",
        "constants": {"delta": delta * L},
        "mesh": {
            "type": "rectangle" if dim == 2 else "box",
            "corners": [lower, upper],
            "cells": list(cells),
        },
        "boundaries": {
            "top": {"role": "contact", "where": f"{last} > -1e-10*{L}"},
            "bottom": {"role": "dirichlet", "where": f"{last} < -{L} + 1e-10*{L}"},
        },
        "model": {"type": "hyperelastic", "law": "neo_hookean", "E": E, "nu": NU},
        "obstacle": {"type": "circle" if dim == 2 else "sphere", "center": centre, "radius": L / 2},
        "output": {"verbose": False},
    }
    if u_D is not None:
        cfg["data"] = {"u_D": u_D}
    if friction is not None:
        cfg["friction"] = friction
    return cfg


def fixed_obstacle(dim: int, push: list, friction: dict | None = None) -> dict:
    """The indentation block against a fixed circle / sphere touching its top at the
    origin, pushed up by its clamped bottom (u_D = ``push``)."""
    cfg = indentation(dim, friction=friction, u_D=push)
    cfg["obstacle"]["center"] = [0.1] + [0.2] * (dim - 2) + [0.5]
    return cfg


def jacobian_error(cfg: dict, curvature: bool = True, seed: int = 0) -> tuple[float, int]:
    """max |H v − (Φ(x + εv) − Φ(x − εv)) / 2ε| / max |H v| at ε = 10⁻⁶ and the number of
    active nodes, x the solution perturbed by 10⁻³ (random, off the kinks of Φ), v random."""
    scene = contact.load_scene(cfg)
    r = contact.solve(scene, method="fb")
    assert r.converged, r.reason
    p = r.problem
    x = p.b.duplicate()
    p.to_unknowns(r.u_h.x.petsc_vec, x)
    free = np.ones(x.getLocalSize(), dtype=bool)
    for bc in p.bcs:
        fixed = bc.dof_indices()[0]
        free[fixed[fixed < len(free)]] = False
    rng = np.random.default_rng(seed)
    x.array[free] += 1e-3 * rng.standard_normal(int(free.sum()))
    cp = CurrentComplementarity(p)
    cp.curvature = curvature
    H = cp.matrix()
    cp.block_jacobian(x, H, "fb", 0.5)
    v = x.duplicate()
    v.array[:] = rng.standard_normal(len(free)) * free
    Hv, f_plus, f_minus = x.duplicate(), x.duplicate(), x.duplicate()
    H.mult(v, Hv)
    eps = 1e-6
    for sign, f in ((1.0, f_plus), (-1.0, f_minus)):
        y = x.copy()
        y.axpy(sign * eps, v)
        cp.phi(y, f, "fb", 0.5)
        y.destroy()
    fd = (f_plus.array - f_minus.array) / (2 * eps)
    a, b, _ = cp.pair(x)
    active = int(cp.active_set(a, b).sum())
    error = float(np.max(np.abs(fd - Hv.array)) / np.max(np.abs(Hv.array)))
    for obj in (H, v, Hv, f_plus, f_minus, x):
        obj.destroy()
    cp.destroy()
    return error, active


COULOMB = {"law": "coulomb", "coefficient": 0.3, "form": "projection"}


@pytest.mark.parametrize(
    "dim, friction, quarter",
    [
        (2, None, False),
        (3, None, False),
        (2, COULOMB, False),
        (3, COULOMB, False),
        (3, COULOMB, True),
    ],
)
def test_the_generalized_jacobian_is_the_derivative(dim, friction, quarter):
    """Where Φ is differentiable (a perturbed solution: R_t ≠ 0, nodes in contact) H = B K_T
    + D is its derivative: the central difference agrees to O(ε²) (≤ 1e-6 relative; measured
    1e-9..5e-9), the 3D spin of the frame and Coulomb's coupling included (the projection
    form: HSW's element is not the exact derivative off the solution), and on a quarter
    model whose contact nodes on the symmetry planes keep one or two fixed axes in their
    frames.  Without the curvature term S M(R) Dñ the error is ≥ 1e-4 (measured
    1e-3..1e-2): the term is there."""
    push = ["0.02", "0.1"] if dim == 2 else ["0.02", "0.01", "0.15"]
    cfg = fixed_obstacle(dim, push, friction)
    if dim == 3:
        cfg["mesh"]["cells"] = [4, 4, 2]
    if quarter:  # x = 0 and y = 0 symmetry planes through the sphere's centre
        cfg["mesh"]["corners"] = [[0, 0, -1], [1, 1, 0]]
        cfg["boundaries"].update(
            sym_x={"role": "symmetry", "where": "x < 1e-10"},
            sym_y={"role": "symmetry", "where": "y < 1e-10"},
        )
        cfg["obstacle"]["center"] = [0, 0, 0.5]
        cfg["data"]["u_D"] = ["0", "0", "0.15"]
    error, active = jacobian_error(cfg)
    assert active >= 2
    assert error <= 1e-6
    assert jacobian_error(cfg, curvature=False)[0] >= 1e-4


def arch_on(obstacle: dict) -> dict:
    """tests/test_hyperelastic.py's arch (a curved bottom y = 0.2 x², the top clamped) pressed
    by the rising obstacle to delta = 0.1 in 4 load steps."""
    return {**arch("neo_hookean"), "load": {"steps": 4}, "obstacle": obstacle}


def test_a_huge_circle_is_the_plane():
    """The arch pressed onto the plane y = δt (the nodal bound, contact/models/obstacles.py)
    and onto circles of radius R whose top rises the same way (the gap on the current
    configuration): u_h differs by c/R (R = 10³ and 10⁴: c equal to 2 %; measured 1.718 and
    1.718, 1e-5 at R = 10⁵, 1.7e-6 at 10⁶), the force by O(1/R), the active nodes equal.  A
    circle of radius 10⁴ computes its gap |x − c| − R with round-off 10⁻¹², which the stopping
    test accounts for (it stalled above the tolerance before)."""
    plane = contact.run_load_path(
        contact.load_scene(arch_on({"type": "plane", "point": [0, "delta*t"], "normal": [0, 1]}))
    )
    ref = plane.steps[-1].result
    u_ref = ref.u_h.x.array.copy()
    scale = float(np.max(np.abs(u_ref)))
    c = []
    for R in (1e3, 1e4):
        circle = {"type": "circle", "center": [0, f"delta*t - {R}"], "radius": R}
        path = contact.run_load_path(contact.load_scene(arch_on(circle)))
        assert path.converged, path.stop
        r = path.steps[-1].result
        assert r.n_active == ref.n_active > 1
        assert abs(r.contact_force / ref.contact_force - 1) < 2 / R
        c.append(R * float(np.max(np.abs(r.u_h.x.array - u_ref))) / scale)
    assert c[1] == pytest.approx(c[0], rel=0.02) and 0.1 < c[0] < 10


def linearized_sequence(scene, tol: float = 1e-13, max_outer: int = 40):
    """The independent solver: u^{k+1} = the vinewtonrsls solution of the problem with the
    gap linearized at u^k (contact.models.hyperelastic.linearized_problem), until u stops
    moving.  Returns (u, outer iterations)."""
    p = build_problem(scene)
    comm = scene.comm
    u = fem.Function(p.V)
    for k in range(max_outer):
        p.u_h.x.array[:] = u.x.array
        lin = linearized_problem(p)
        r = contact.solve(scene, method="vinewtonrsls", problem=lin, u0=u)
        assert r.converged, r.reason
        change = comm.allreduce(float(np.max(np.abs(r.u_h.x.array - u.x.array))), op=MPI.MAX)
        size = comm.allreduce(float(np.max(np.abs(r.u_h.x.array))), op=MPI.MAX)
        u.x.array[:] = r.u_h.x.array
        lin.destroy()
        if change <= tol * size:
            return u, k + 1, r.contact_force
    raise AssertionError("the linearized sequence did not settle")


@pytest.mark.parametrize("dim", [2, 3])
def test_semismooth_newton_agrees_with_a_sequence_of_linearized_vi_solves(dim):
    """The same discrete problem (a circle / sphere lowered and moved sideways into the
    block, 0.1 (2D) or 0.3 (3D) of its radius, one step from u = 0) solved by fb, min and
    blend and by the independent sequence of vinewtonrsls solves: u_h agrees to 1e-8
    relative (measured 1.1e-10 in 2D, 4.3e-10 in 3D), the force to 1e-8.  Why not closer:
    the sequence converges linearly (contraction ≈ 0.13 per solve) and stops when a VI
    solve no longer moves, and PETSc's VI solvers hold a variable within 1e-8 (absolute,
    SNESVIGetActiveSetIS) of its bound as active, so the scene is in units where
    max |u| ≈ 5 (L = 100): 2e-9 relative."""
    cells, delta = ((40, 20), 0.05) if dim == 2 else ((8, 8, 4), 0.15)
    scene = contact.load_scene(indentation(dim, delta=delta, cells=cells, scale=100.0))
    u_vi, outer, force_vi = linearized_sequence(scene)
    assert outer > 3  # the normals moved: one linearized solve is not the answer
    size = float(np.max(np.abs(u_vi.x.array)))
    for method in ("fb", "min", "blend"):
        r = contact.solve(scene, method=method)
        assert r.converged, (method, r.reason)
        diff = scene.comm.allreduce(float(np.max(np.abs(r.u_h.x.array - u_vi.x.array))), op=MPI.MAX)
        assert diff <= 1e-8 * size, (method, diff / size)
        assert r.contact_force == pytest.approx(force_vi, rel=1e-8)


def turned_block(theta: float, steps: int = 16) -> dict:
    """A block [−0.5, 0.5] × [0, 0.5] on the rigid circle of radius 0.5 centred at c = (0, −0.5):
    its clamped top pressed down by 0.05 (t ≤ 1/2), then turned about c by θ with the whole
    block (t > 1/2): x_D = Rot(θ(t)) (X − c − p(t) e_y) + c."""
    p = "(0.05*min(1, 2*t))"
    th = f"({theta}*max(0, 2*t - 1))"
    X, Y = "x", f"(y + 0.5 - {p})"
    return {
        "name": "turned",
        "mesh": {"type": "rectangle", "corners": [[-0.5, 0], [0.5, 0.5]], "cells": [16, 8]},
        "boundaries": {
            "bottom": {"role": "contact", "where": "y < 1e-10"},
            "top": {"role": "dirichlet", "where": "y > 0.5 - 1e-10"},
        },
        "model": {"type": "hyperelastic", "law": "neo_hookean", "E": E, "nu": NU},
        "obstacle": {"type": "circle", "center": [0, -0.5], "radius": 0.5},
        "data": {
            "u_D": [
                f"cos{th}*{X} + sin{th}*{Y} - x",
                f"-sin{th}*{X} + cos{th}*{Y} - 0.5 - y",
            ]
        },
        "load": {"steps": steps},
        "output": {"verbose": False},
    }


def test_large_sliding_round_the_circle_is_the_turned_solution():
    """Frame invariance with large sliding: the block pressed onto the circle and then turned
    about its centre by θ = 0.6 rad — its contact nodes slide R θ = 0.3 (5 cells) along the
    circle, each meeting new parts of it — ends in the pressed solution turned by θ: the
    deformed positions agree to 1e-10 (measured 2e-16), the same active nodes, the resultant
    contact force turned by θ."""
    theta = 0.6
    # frictionless: the pressed state does not depend on the path (pressing ends at t = 1/2)
    pressed = contact.run_load_path(contact.load_scene(turned_block(0.0, 2))).steps[-1].result
    path = contact.run_load_path(contact.load_scene(turned_block(theta)))
    assert path.converged, path.stop
    turned = path.steps[-1].result
    X = pressed.u_h.function_space.tabulate_dof_coordinates()[:, :2]
    c = np.array([0.0, -0.5])
    rot = np.array([[np.cos(theta), np.sin(theta)], [-np.sin(theta), np.cos(theta)]])
    x_pressed = X + pressed.u_h.x.array.reshape(-1, 2)
    x_turned = X + turned.u_h.x.array.reshape(-1, 2)
    assert np.max(np.abs(x_turned - ((x_pressed - c) @ rot.T + c))) <= 1e-10
    assert turned.n_active == pressed.n_active >= 4
    F_pressed, F_turned = force_vector(pressed), force_vector(turned)
    assert np.max(np.abs(F_turned - rot @ F_pressed)) <= 1e-10 * np.linalg.norm(F_pressed)


def force_vector(result) -> np.ndarray:
    """The resultant −Σ_i R_i of the nodal contact forces on the body (all ranks)."""
    p = result.problem
    bs = p.V.dofmap.index_map_bs
    rows = p.current.nodes[:, None] * bs + np.arange(bs)
    local = -owned_residual(result)[rows].sum(axis=0)
    return p.V.mesh.comm.allreduce(local, op=MPI.SUM)


def test_small_indentation_is_the_linear_hertz_scene():
    """configs/indentation_2d.yaml (a block under a rigid cylinder of radius 5) at
    indentation 0.001 with the neo-Hookean law on the current configuration: the contact
    half-width a (the active measure) and the peak pressure p0 of the linear scene (its
    normals fixed at the reference) within 0.5 % (measured: a equal, p0 −0.05 % on
    160 × 80 cells, −0.04 % here), and not equal to round-off."""
    sets = ["mesh.cells=[80,40]", "output.verbose=false", "reference=none", "constants.delta=0.001"]
    figures = []
    for model in (["model.type=elasticity"], ["model.type=hyperelastic", "model.law=neo_hookean"]):
        scene = contact.load_scene(ROOT / "configs" / "indentation_2d.yaml", sets + model)
        r = contact.solve(scene, method="fb")
        assert r.converged
        figures.append(
            (active_measure(r), contact_resultants(posed_of(scene), r)["peak_pressure"], r)
        )
    (a, p0, lin), (a_h, p0_h, hyp) = figures
    assert hyp.n_active == lin.n_active >= 4
    assert abs(a_h / a - 1) < 5e-3 and abs(p0_h / p0 - 1) < 5e-3
    assert abs(p0_h / p0 - 1) > 1e-6


@pytest.mark.parametrize("dim", [2, 3])
def test_newton_converges_superlinearly(dim):
    """The circle / sphere lowered into the block in 3 load steps: each step takes ≤ 8 Newton
    iterations and, above round-off, the contraction factor q_k = r_{k+1}/r_k of its last two
    steps falls by ≥ 10× (a linear rate keeps it constant)."""
    cells = (24, 12) if dim == 2 else (6, 6, 3)
    cfg = {**indentation(dim, delta=0.15, cells=cells), "load": {"steps": 3}}
    path = contact.run_load_path(contact.load_scene(cfg))
    assert path.converged, path.stop
    assert superlinear_steps(path) >= 2


@pytest.mark.parametrize(
    "change, key",
    [
        ({"solver": {"method": "vinewtonrsls"}}, "solver.method: vinewtonrsls needs a gap"),
        (
            {"friction": {"law": "coulomb", "coefficient": 0.3, "coulomb": "fixed_point"}},
            "friction.coulomb: fixed_point",
        ),
        ({"obstacle": {"type": "circle", "center": [0, "x"], "radius": 1}}, "obstacle.center:"),
    ],
)
def test_bad_input_names_the_key(change, key):
    with pytest.raises(ConfigError, match=f"^{key}"):
        contact.load_scene({**indentation(), **change})


def test_an_api_call_with_a_vi_method_names_the_key():
    """contact.solve(method=...) overrides the scene's method after validation: refused there."""
    scene = contact.load_scene(indentation())
    with pytest.raises(ConfigError, match="^solver.method: vinewtonrsls needs a gap"):
        contact.solve(scene, method="vinewtonrsls")


# ------------------------------------------------------------------- Coulomb friction
def dragged_block(method: str, form: str = "hsw"):
    """configs/hyperelastic_drag.yaml on 20 × 5 cells: pressed by 0.05 (t ≤ 0.2), then
    dragged by 0.3 — six times the press — in 8 steps; every step kept."""
    scene = contact.load_scene(
        ROOT / "configs" / "hyperelastic_drag.yaml",
        ["mesh.cells=[20,5]", "output.verbose=false", f"friction.form={form}"],
    )
    return contact.run_load_path(scene, method=method, keep_all=True)


@pytest.mark.parametrize("method, form", [("fb", "hsw"), ("min", "hsw"), ("fb", "projection")])
def test_a_dragged_block_slides_with_F_times_the_normal_force(method, form):
    """Coulomb friction on the current tangent plane, a known answer: the block pressed onto
    the plane sticks (most nodes), goes through partial slip and then slides as a whole:
    there the friction force is F = 0.3 times the normal force (1e-8, from the nodal
    tractions), the supports' reaction balances both (1e-8), and each step is the previous
    state translated by the drag's step (1e-10: the slip is the increment of the deformed
    position, the same at every node)."""
    path = dragged_block(method, form)
    assert path.converged, path.stop
    full = 0
    previous = None
    for step in path.steps:
        r = step.result
        f = r.friction
        Fn = r.u_h.function_space.mesh.comm.allreduce(float(np.sum(f["w"] * f["lambda_n"])))
        Ft = r.u_h.function_space.mesh.comm.allreduce(float(np.sum(f["w"] * f["lambda_t"][:, 0])))
        reaction = reaction_force(r)
        assert reaction[0] == pytest.approx(-Ft, rel=1e-8, abs=1e-12)
        assert reaction[1] == pytest.approx(Fn, rel=1e-8)
        pressed = f["lambda_n"] < -1e-8 * np.max(np.abs(f["lambda_n"]))
        if step.time <= 0.2 + 1e-12:
            assert np.sum(f["status"][pressed] == 1) > pressed.sum() / 2  # mostly stick
        if np.all(f["status"][pressed] == 2):
            full += 1
            assert Ft == pytest.approx(0.3 * Fn, rel=1e-8)
            if previous is not None and previous[1]:
                shift = r.u_h.x.array.reshape(-1, 2) - previous[0].reshape(-1, 2)
                assert np.max(np.abs(shift - [0.3 * (step.time - previous[2]) / 0.8, 0])) < 1e-10
        previous = (r.u_h.x.array.copy(), bool(np.all(f["status"][pressed] == 2)), step.time)
    assert full >= 5


def test_sliding_round_a_circle_with_friction_is_steady():
    """The block pressed onto the circle with Coulomb friction (F = 0.3) sticks; turned about
    the circle's centre it slides round it, and once every contact node slips each step is
    the previous state turned by the step's angle (1e-10; measured 1e-14): friction acts on
    the current tangent of the circle, however far the nodes have slid; at each slipping
    node |λ_t| = F |λ_n| (the law, in the current frame)."""
    cfg = turned_block(0.6)
    cfg["friction"] = {"law": "coulomb", "coefficient": 0.3}
    path = contact.run_load_path(contact.load_scene(cfg), keep_all=True)
    assert path.converged, path.stop
    c = np.array([0.0, -0.5])
    steady, previous = 0, None
    for step in path.steps:
        r, f = step.result, step.result.friction
        X = r.u_h.function_space.tabulate_dof_coordinates()[:, :2]
        x = X + r.u_h.x.array.reshape(-1, 2)
        touching = f["status"] > 0
        if step.time == 0.5:
            assert np.sum(f["status"] == 1) >= 3  # pressed: stick
        sliding = bool(touching.sum() >= 4 and np.all(f["status"][touching] == 2))
        if sliding:
            lam_t = np.linalg.norm(f["lambda_t"], axis=1)[touching]
            assert np.max(np.abs(lam_t - 0.3 * np.abs(f["lambda_n"][touching]))) < 1e-10
        if sliding and previous is not None and previous[2]:
            angle = 0.6 * (max(0.0, 2 * step.time - 1) - max(0.0, 2 * previous[0] - 1))
            rot = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
            assert np.max(np.abs(x - ((previous[1] - c) @ rot.T + c))) <= 1e-10
            steady += 1
        previous = (step.time, x, sliding)
    assert steady >= 5


# ------------------------------------------------------------- pressure on the deformed surface
@pytest.mark.parametrize("dim", [2, 3])
def test_the_pressure_per_deformed_area_is_the_cauchy_traction(dim):
    """The homogeneous 30 % compression of tests/test_hyperelastic.py (P1 represents it
    exactly): the nominal pressure is −P₂₂ and the pressure per deformed area
    (contact.csv's pressure_current, w_i p_i / ∫ φ_i J |F⁻ᵀN| dA) is the Cauchy stress
    −σ₂₂ = −P₂₂ / λ₁^(d−1) at every contact node, λ₁ the lateral stretch (1e-8)."""
    from contact.models.hyperelastic import uniaxial_stretch
    from contact.post.contact_table import contact_columns
    from contact.post.resultants import current_pressure

    from test_hyperelastic import block

    scene = contact.load_scene(block("neo_hookean", 1, dim))
    r = contact.solve(scene, method="fb")
    assert r.converged
    l1, P22 = uniaxial_stretch("neo_hookean", E, NU, 0.7, dim)
    current = current_pressure(r)
    assert len(current) and np.max(np.abs(current / (-P22 / l1 ** (dim - 1)) - 1)) < 1e-8
    cols = contact_columns(posed_of(scene), r)
    assert np.array_equal(cols["pressure_current"], current)
    assert np.max(np.abs(cols["lambda_n"] / P22 - 1)) < 1e-8  # nominal: λ = P₂₂ < 0


def test_cli_sphere_indentation_writes_both_pressures(tmp_path):
    """``contact run configs/hyperelastic_sphere.yaml`` (a rubber block under a rigid sphere,
    3D, quarter model) on a coarse mesh: exit 0; steps.csv has per step the force of the
    whole block (growing with the indentation δ t) and the peak pressures, nominal and per
    deformed area; contact.csv both at every node; the XDMF holds pressure_current.  The
    contact force equals the bottom's reaction (equilibrium, 1e-8)."""
    import csv

    from clirun import contact as cli

    scene = str(ROOT / "configs" / "hyperelastic_sphere.yaml")
    sets = ["mesh.cells=[4,4,3]", "load.steps=3", "output.png=false"]
    proc = cli(tmp_path, "run", scene, "-o", "out", "-q", *[a for s in sets for a in ("--set", s)])
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader(open(tmp_path / "out" / "steps.csv")))
    forces = [float(r["contact_force"]) for r in rows]
    assert len(rows) == 3 and 0 < forces[0] < forces[1] < forces[2]
    assert [float(r["time"]) for r in rows] == pytest.approx([1 / 3, 2 / 3, 1])  # δ t
    assert all(
        float(r["peak_pressure_current"]) > 0 and float(r["peak_pressure"]) > 0 for r in rows
    )
    table = list(csv.DictReader(open(tmp_path / "out" / "contact.csv")))
    assert {"lambda_n", "pressure_current", "gap"} <= set(table[0])
    assert "pressure_current" in (tmp_path / "out" / "solution_002.xdmf").read_text()
    loaded = contact.load_scene(scene, sets)
    r = contact.run_load_path(loaded).steps[-1].result
    res = contact_resultants(posed_of(loaded), r)
    assert res["force_balance_error"] < 1e-8 and r.contact_force == pytest.approx(forces[-1])


@pytest.mark.parametrize("obstacle", ["circle", "plane"])
def test_friction_against_a_moving_obstacle_is_the_moved_body(obstacle):
    """Galilean invariance of friction: the obstacle lowered and moved sideways by
    d(t) = (0.3 δt, −δt) into a block held at its bottom, and the block's bottom moved by
    −d(t) under the obstacle held still, are the same problem seen from two frames:
    u_moved-body = u_moved-obstacle − d at every node and step (1e-10 of max |u|, measured
    4e-14; Coulomb F = 0.5, nodes sticking and slipping).  The slip is relative to the
    obstacle: its translation Δc since the previous step (since t = 0 on the first) is
    taken off — without it the sticking nodes stayed behind the obstacle, 5e-3 off)."""
    delta, steps = 0.05, 3
    moving = {**indentation(cells=(16, 8), delta=delta), "load": {"steps": steps}}
    moving["friction"] = {"law": "coulomb", "coefficient": 0.5}
    if obstacle == "plane":
        moving["obstacle"] = {
            "type": "plane",
            "point": ["0.3*delta*t", "-delta*t"],
            "normal": [0, -1],
        }
    still = {
        **moving,
        "obstacle": {
            **moving["obstacle"],
            **(
                {"center": [0, 0.5]}
                if obstacle == "circle"
                else {"point": [0, 0], "normal": [0, -1]}
            ),
        },
        "data": {"u_D": ["-0.3*delta*t", "delta*t"]},
    }
    a = contact.run_load_path(contact.load_scene(moving), keep_all=True)
    b = contact.run_load_path(contact.load_scene(still), keep_all=True)
    assert a.converged and b.converged
    for sa, sb in zip(a.steps, b.steps):
        d = np.array([0.3 * delta * sa.time, -delta * sa.time])
        ua = sa.result.u_h.x.array.reshape(-1, 2)
        ub = sb.result.u_h.x.array.reshape(-1, 2)
        assert np.max(np.abs(ub - (ua - d))) <= 1e-10 * np.max(np.abs(ua))
    status = np.concatenate([s.result.friction["status"] for s in a.steps])
    assert np.sum(status == 1) >= 1 and np.sum(status == 2) >= 1


def test_the_stability_check_uses_the_hessian_of_the_lagrangian():
    """negative_eigenvalues on the current configuration: the inertia of the Hessian of the
    Lagrangian ∇²L = K_T − Σ μ_i P Dn_i P (μ_i = ñ_i·R_i) on the tangent space of the active
    constraints (their normal unknowns held, in their current frames).  For a direction v
    tangent at the active nodes, zᵀ Ã z (z = Qᵀ v, zero on the held rows) equals the central
    difference of ∇L(u) = R(u) + Σ_i μ_i ∇g_i(u) at fixed μ (1e-6), and differs from vᵀ K_T v
    by the obstacle's curvature; the indentation is stable (no negative eigenvalue)."""
    from contact.models.hyperelastic import negative_eigenvalues

    scene = contact.load_scene(fixed_obstacle(2, ["0.02", "0.1"]))
    r = contact.solve(scene, method="fb")
    assert r.converged and r.n_active >= 2
    p = r.problem
    cc, bs = p.current, 2
    x = p.b.duplicate()
    p.to_unknowns(r.u_h.x.petsc_vec, x)
    A, held = p.constrained_hessian(x, r.active_mask)
    rows = cc.nodes[:, None] * bs + np.arange(bs)
    R0 = owned_residual(r)
    g_n = cc.surface.project(cc.X + x.array_r[rows])[1]
    mu = np.einsum("ka,ka->k", g_n, R0[rows])  # μ_i = n_i·R_i (no fixed components here)
    free = np.ones(x.getLocalSize(), dtype=bool)
    for bc in p.bcs:
        fixed = bc.dof_indices()[0]
        free[fixed[fixed < len(free)]] = False
    rng = np.random.default_rng(1)
    vv = (rng.standard_normal(len(free)) * free).reshape(-1, bs)
    on = cc.nodes[r.active_mask]
    n_on = g_n[r.active_mask]
    vv[on] -= np.einsum("ka,ka->k", vv[on], n_on)[:, None] * n_on  # tangent at active nodes
    v = x.duplicate()
    v.array[:] = vv.ravel()

    def grad_L(y: np.ndarray) -> np.ndarray:
        z = x.duplicate()
        z.array[:] = y
        out = z.duplicate()
        p.residual(z, out)
        g = out.array.copy()
        _, n, _ = cc.surface.project(cc.X + y[rows])
        g[rows[r.active_mask]] -= (mu[:, None] * n)[r.active_mask]  # + μ ∇g, ∇g = −n
        z.destroy()
        out.destroy()
        return g

    eps = 1e-6
    fd = (grad_L(x.array + eps * v.array) - grad_L(x.array - eps * v.array)) / (2 * eps)
    Q = np.tile(np.eye(bs), (len(free) // bs, 1, 1))
    Q[on] = nodal_geometry(cc, x.array_r[rows]).frames[r.active_mask]  # the active nodes
    z = x.duplicate()
    z.array[:] = np.einsum("kab,ka->kb", Q, vv).ravel()  # z = Qᵀ v
    assert np.max(np.abs(z.array[held])) < 1e-12  # tangent: the held normal parts vanish
    Az = z.duplicate()
    A.mult(z, Az)
    quadratic, expected = float(z.dot(Az)), float(v.array @ fd)
    assert quadratic == pytest.approx(expected, rel=1e-6)
    p.linearize(x)
    Kv = v.duplicate()
    p.K.mult(v, Kv)
    assert abs(float(v.dot(Kv)) - expected) > 1e-3 * abs(expected)  # the curvature counts
    assert negative_eigenvalues(r) == 0
    for obj in (A, x, v, z, Az, Kv):
        obj.destroy()
