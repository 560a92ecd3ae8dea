"""Hyperelastic bodies against rigid planes (issue 31, first slice): model.type hyperelastic,
neo-Hookean and St Venant–Kirchhoff, P1 / P2, 2D plane strain and 3D.

Checked against exact solutions and independent solvers: homogeneous compression (P1 and
P2 represent it exactly: the nodal pressures, the force per area and the displacement are
the analytic uniaxial response, the lateral stretch a scalar root); PETSc's vinewtonrsls on
the same discrete problem (a curved body pressed by a moving plate: the contact zone is an
unknown); the linear model in the small-load limit; step cutting on a step whose start
inverts cells; the CLI's steps.csv (force per step).  Serial = 2 and 3 ranks: the shipped
scene configs/hyperelastic_block.yaml is in tests/test_cli_mpi.py."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import contact
from contact import ConfigError
from contact.models.hyperelastic import uniaxial_stretch
from contact.post.resultants import contact_resultants
from contact.setup.posed import posed_of
from contact.solvers import owned_residual

import numpy as np
import pytest
from clirun import ROOT
from clirun import contact as cli
from mpi4py import MPI

LAWS = ("neo_hookean", "saint_venant_kirchhoff")
E, NU = 1.0, 0.3


def block(law: str, degree: int = 1, dim: int = 2, compression: float = 0.3) -> dict:
    """The unit square / cube, a quarter (eighth) of a block: symmetry planes x = 0 (and
    y = 0 in 3D) and the frictionless floor as the symmetry plane of the last axis; the
    rigid plate at 1 − compression presses the top."""
    names = "xyz"[:dim]
    last = names[-1]
    parts = {f"sym_{c}": {"role": "symmetry", "where": f"{c} < 1e-10"} for c in names}
    parts["top"] = {"role": "contact", "where": f"{last} > 1 - 1e-10"}
    mesh = {
        "type": "rectangle" if dim == 2 else "box",
        "corners": [[0] * dim, [1] * dim],
        "cells": [3] * dim if dim == 2 else [2] * dim,
        "degree": degree,
    }
    return {
        "name": "block",
        "mesh": mesh,
        "boundaries": parts,
        "model": {"type": "hyperelastic", "law": law, "E": E, "nu": NU},
        "obstacle": {
            "type": "plane",
            "point": [0] * (dim - 1) + [1 - compression],
            "normal": [0] * (dim - 1) + [-1],
        },
        "output": {"verbose": False},
    }


def arch(
    law: str = "neo_hookean",
    delta: float = 0.1,
    model: str = "hyperelastic",
    cells: tuple = (12, 6),
    c: float = 0.2,
) -> dict:
    """A body with a curved bottom y = c x² (x ∈ [0, 1], the axis x = 0 a symmetry
    plane), its flat top y = 0.5 clamped, pressed by the rigid plate y = delta·t from below:
    the contact zone grows from the axis and is an unknown of the problem."""
    m = {"type": model, "E": E, "nu": NU, **({"law": law} if model == "hyperelastic" else {})}
    return {
        "name": "arch",
        "constants": {"delta": delta},
        "mesh": {
            "type": "rectangle",
            "corners": [[0, 0], [1, 0.5]],
            "cells": list(cells),
            "map": ["x", f"y + {c}*x*x*(1 - 2*y)"],
        },
        "boundaries": {
            "axis": {"role": "symmetry", "where": "x < 1e-10"},
            "bottom": {"role": "contact", "where": f"y < {c}*x*x + 1e-10"},
            "top": {"role": "dirichlet", "where": "y > 0.5 - 1e-10"},
        },
        "model": m,
        "obstacle": {"type": "plane", "point": [0, "delta*t"], "normal": [0, 1]},
        "output": {"verbose": False},
    }


def tilted_arch(theta: float, law: str, delta: float = 0.1, drive: str = "top") -> dict:
    """The whole arch (x ∈ [−1, 1], bottom y = 0.2 x²) pressed onto the plane with normal
    ν = (−sin θ, cos θ) through 0 by its clamped top moved δt along −ν (``drive="top"``), or
    by the plane moved δt along ν with the top held (``"plane"``): the scene at θ = 0
    rotated by θ as a whole (mesh, plane, loads)."""
    co, si = np.cos(theta), np.sin(theta)
    top = [f"{si}*delta*t", f"{-co}*delta*t"] if drive == "top" else ["0", "0"]
    point = [0, 0] if drive == "top" else [f"{-si}*delta*t", f"{co}*delta*t"]
    xr, yr = f"({co}*x + {si}*y)", f"({-si}*x + {co}*y)"  # the coordinates before the rotation
    bottom = "(y + 0.2*x*x*(1 - 2*y))"
    return {
        "name": "tilted",
        "constants": {"delta": delta},
        "mesh": {
            "type": "rectangle",
            "corners": [[-1, 0], [1, 0.5]],
            "cells": [16, 4],
            "map": [f"{co}*x - {si}*{bottom}", f"{si}*x + {co}*{bottom}"],
        },
        "boundaries": {
            "bottom": {"role": "contact", "where": f"{yr} < 0.2*{xr}**2 + 1e-9"},
            "top": {"role": "dirichlet", "where": f"{yr} > 0.5 - 1e-9"},
        },
        "model": {"type": "hyperelastic", "law": law, "E": E, "nu": NU},
        "obstacle": {"type": "plane", "point": point, "normal": [-si, co]},
        "data": {"u_D": top},
        "load": {"steps": 4},
        "output": {"verbose": False},
    }


def nodal_pressure(result) -> tuple[np.ndarray, np.ndarray]:
    """(p_i, w_i) at the owned contact nodes (p = nominal pressure, force per reference area)."""
    p = result.problem
    return p.pressure(owned_residual(result)), p.constraint.w


@pytest.mark.parametrize(
    "law, degree, dim",
    [
        ("neo_hookean", 1, 2),
        ("saint_venant_kirchhoff", 1, 2),
        ("neo_hookean", 2, 2),
        ("neo_hookean", 1, 3),
        ("saint_venant_kirchhoff", 1, 3),
    ],
)
def test_homogeneous_compression_matches_the_analytic_response(law, degree, dim):
    """30 % compression in one solve from u = 0: F = diag(λ₁, (λ₁,) 0.7) exactly, with λ₁
    the root of P₁₁ = 0; the plate's nominal pressure is −P₂₂ at every contact node and on
    average (force / area), the displacement (λ − 1) X at every node, all to 1e-8."""
    scene = contact.load_scene(block(law, degree, dim))
    r = contact.solve(scene, method="fb")
    assert r.converged, r.reason
    l1, P22 = uniaxial_stretch(law, E, NU, 0.7, dim)
    assert P22 < 0 and l1 > 1
    p, w = nodal_pressure(r)
    assert len(p) and np.max(np.abs(p / -P22 - 1)) < 1e-8
    comm = scene.comm
    force, area = comm.allreduce(float(np.sum(w * p))), comm.allreduce(float(np.sum(w)))
    assert force / area == pytest.approx(-P22, rel=1e-8)
    # the whole block's force: the images across x = 0 (and y = 0) press alongside, the one
    # across the floor (normal to the force) is a second plate, not counted: 2^(dim-1) tops
    assert r.problem.symmetry.copies == 2**dim and area == pytest.approx(1.0)
    assert r.contact_force == pytest.approx(-(2 ** (dim - 1)) * P22, rel=1e-8)
    assert r.problem.copies_along(np.eye(dim)[0]) == 2 ** (dim - 1)  # a force along x
    X = r.u_h.function_space.tabulate_dof_coordinates()[:, :dim]
    exact = X * np.r_[[l1 - 1] * (dim - 1), -0.3]
    assert np.max(np.abs(r.u_h.x.array.reshape(-1, dim) - exact)) < 1e-8
    # the output's von Mises stress: of the Cauchy stress σ = J⁻¹ F S Fᵀ (σ_33 ≠ 0 in 2D)
    from contact.models.elasticity import von_mises
    from contact.models.physics import lame

    vm = von_mises(r.u_h, None, None, r.problem.data.stresses).x.array
    F = np.diag([l1] * (dim - 1) + [0.7] + [1.0] * (3 - dim))
    mu, lm = lame(E, NU)
    Ei = (F.T @ F - np.eye(3)) / 2
    if law == "neo_hookean":  # S = μ (I − C⁻¹) + λ ln J C⁻¹
        Ci = np.linalg.inv(F.T @ F)
        S = mu * (np.eye(3) - Ci) + lm * np.log(np.linalg.det(F)) * Ci
    else:  # S = λ tr E I + 2μ E
        S = lm * np.trace(Ei) * np.eye(3) + 2 * mu * Ei
    sigma = F @ S @ F.T / np.linalg.det(F)
    dev = sigma - np.trace(sigma) / 3 * np.eye(3)
    assert len(vm) and np.max(np.abs(vm / np.sqrt(1.5 * np.sum(dev * dev)) - 1)) < 1e-8


@pytest.mark.parametrize("law", LAWS)
def test_p2_homogeneous_compression_in_3d(law):
    """P2 on tetrahedra, 30 % compression in one solve: the displacement (λ − 1) X at every
    node and the plate's force −4 P₂₂ (force per area −P₂₂) to 1e-8.  The nodal pressures
    R_i / w_i are not uniform here: a uniform pressure's P2 nodal forces vanish at the
    triangles' vertices, the lumped weights (P1-iso-P2) do not (contact/models/problem.py)."""
    scene = contact.load_scene(block(law, 2, 3))
    r = contact.solve(scene, method="fb")
    assert r.converged, r.reason
    l1, P22 = uniaxial_stretch(law, E, NU, 0.7, 3)
    p, w = nodal_pressure(r)
    comm = scene.comm
    force, area = comm.allreduce(float(np.sum(w * p))), comm.allreduce(float(np.sum(w)))
    assert area == pytest.approx(1.0, rel=1e-12)
    assert force / area == pytest.approx(-P22, rel=1e-8)
    assert r.contact_force == pytest.approx(-4 * P22, rel=1e-8)
    X = r.u_h.function_space.tabulate_dof_coordinates()
    exact = X * np.r_[l1 - 1, l1 - 1, -0.3]
    assert np.max(np.abs(r.u_h.x.array.reshape(-1, 3) - exact)) < 1e-8


@pytest.mark.parametrize("law", LAWS)
def test_semismooth_newton_agrees_with_vinewtonrsls(law):
    """The same discrete problem (the arch pressed to delta = 0.1, a fifth of its height, in
    4 load steps) solved by fb, min and blend and by PETSc's vinewtonrsls: the same u_h to
    1e-8 (relative to max |u_h|), the same contact force and active set."""
    scene = contact.load_scene({**arch(law), "load": {"steps": 4}})
    ref = contact.run_load_path(scene, method="vinewtonrsls").steps[-1].result
    assert ref.converged and ref.n_active > 1
    u_ref = ref.u_h.x.array.copy()
    scale = scene.comm.allreduce(float(np.max(np.abs(u_ref))), op=MPI.MAX)
    for method in ("fb", "min", "blend"):
        path = contact.run_load_path(scene, method=method)
        r = path.steps[-1].result
        assert path.converged, (method, path.stop)
        diff = scene.comm.allreduce(float(np.max(np.abs(r.u_h.x.array - u_ref))), op=MPI.MAX)
        assert diff <= 1e-8 * scale, (method, diff)
        assert r.n_active == ref.n_active
        assert r.contact_force == pytest.approx(ref.contact_force, rel=1e-8)


@pytest.mark.parametrize(
    "law, drive",
    [("neo_hookean", "top"), ("saint_venant_kirchhoff", "top"), ("neo_hookean", "plane")],
)
def test_a_tilted_plane_is_the_rotated_scene(law, drive):
    """Frame invariance: the arch on the plane y = 0 and the same scene rotated by 0.3 rad
    (a tilted plane: the contact nodes rotated to their (n, t) axes, R̃ = Qᵀ R(Q x),
    K̃ = Qᵀ K_T Q) give the same contact force (1e-10), active nodes and largest |u_h|,
    pushed by the top or by the moving plane; on the tilted plane fb agrees with
    vinewtonrsls (1e-8)."""
    out = {}
    for theta in (0.0, 0.3):
        scene = contact.load_scene(tilted_arch(theta, law, drive=drive))
        for method in ("fb", "vinewtonrsls") if theta else ("fb",):
            path = contact.run_load_path(scene, method=method)
            assert path.converged, (theta, method, path.stop)
            r = path.steps[-1].result
            u = r.u_h.x.array.reshape(-1, 2)
            largest = np.max(np.linalg.norm(u, axis=1))
            out[theta, method] = (r.contact_force, r.n_active, largest, u.copy())
    (F0, n0, u0, _), (F1, n1, u1, x_fb) = out[0.0, "fb"], out[0.3, "fb"]
    assert n0 > 1 and n1 == n0
    assert F1 == pytest.approx(F0, rel=1e-10) and u1 == pytest.approx(u0, rel=1e-10)
    x_vi = out[0.3, "vinewtonrsls"][3]
    assert np.max(np.abs(x_fb - x_vi)) <= 1e-8 * u1


@pytest.mark.parametrize("law", LAWS)
def test_newton_converges_superlinearly(law):
    """Inside a step whose active set is settled, semismooth Newton on the exact tangent
    K_T(x) converges superlinearly: the contraction factor q_k = r_{k+1}/r_k of the last
    two steps above round-off (r > 1e-11 r_0 and 1e-14; the forces are O(1)) falls
    by at least 10× (a linear rate keeps it constant), and each step takes ≤ 8 Newton
    iterations (issue 31's target at the shipped step sizes)."""
    scene = contact.load_scene({**arch(law), "load": {"steps": 4}})
    # the default (the tangent predictor's start): at most 8 either
    default = contact.run_load_path(scene, method="fb")
    assert default.converged and all(s.result.iterations <= 8 for s in default.steps)
    # from the plain start (the previous solution with the new data), where Newton has
    # more than two steps above round-off to show its rate
    path = contact.run_load_path(scene, method="fb", predictor="none")
    assert path.converged
    assert superlinear_steps(path) >= len(path.steps) // 2


def superlinear_steps(path) -> int:
    """Assert ≤ 8 Newton iterations in every step of a load path and, in each step with ≥ 3
    residuals above round-off (r > 1e-11 r_0), a last contraction factor ≥ 10× below the one
    before (superlinear); return how many steps that checked."""
    checked = 0
    for step in path.steps:
        r = [h["residual"] for h in step.result.history]
        assert len(r) <= 9, r
        r = [x for x in r if x > max(1e-11 * r[0], 1e-14)]  # above round-off (absolute too:
        # the tangent predictor may start a step at |Phi| ~ 1e-6)
        if len(r) >= 3:
            q = [b / a for a, b in zip(r, r[1:])]
            assert q[-1] <= 0.1 * q[-2], r
            checked += 1
    return checked


def test_step_cutting_halves_a_step_whose_start_inverts_cells():
    """The clamped top pushed down by 0.1 in one step: the start (the previous solution with
    the new Dirichlet values) inverts the top row of cells (0.075 high at x = 1), so ψ
    (ln J) is undefined and the step fails at iteration 0 — a property of the geometry,
    not of the iteration.  Without cuts (load.cuts: 0) the run stops there; by default the
    step is halved, the cut is reported, and the answer is that of 8 equal steps (1e-8).
    (From the plain start: the tangent predictor, the default, lifts the push into the body
    and needs no cut, test_the_tangent_predictor_saves_the_cut_and_newton_steps.)"""
    cfg = arch(delta=0.1, cells=(8, 4))
    cfg["obstacle"]["point"], cfg["data"] = [0, 0], {"u_D": ["0", "-delta*t"]}
    cfg["solver"] = {"predictor": "none"}
    no_cuts = contact.run_load_path(contact.load_scene({**cfg, "load": {"steps": 1, "cuts": 0}}))
    assert not no_cuts.converged and no_cuts.cuts == []
    assert no_cuts.steps[-1].result.reason == "diverged_function_nanorinf"
    assert no_cuts.steps[-1].result.iterations == 0
    cut = contact.run_load_path(contact.load_scene({**cfg, "load": {"steps": 1}}))
    assert cut.converged, cut.stop
    assert cut.cuts[0] == "t = 1 (diverged_function_nanorinf) cut to t = 0.5"
    assert "step cut(s)" in cut.stop and cut.steps[0].time == 0.5 and cut.steps[-1].time == 1.0
    fine = contact.run_load_path(contact.load_scene({**cfg, "load": {"steps": 8}}))
    assert fine.converged and fine.cuts == []
    a, b = cut.steps[-1].result.u_h.x.array, fine.steps[-1].result.u_h.x.array
    assert np.max(np.abs(a - b)) <= 1e-8 * np.max(np.abs(b))


def test_the_tangent_predictor_saves_the_cut_and_newton_steps():
    """solver.predictor (auto = tangent for this model): the clamped top pushed 0.1 in one
    step, whose plain start inverts cells, starts from the tangent's lift instead: no cut,
    the answer of 8 equal steps (1e-8); the neo-Hookean cylinder pressed to 0.5 R in 5 steps
    takes fewer Newton steps in total than from the plain starts (measured 16 against 21)."""
    cfg = arch(delta=0.1, cells=(8, 4))
    cfg["obstacle"]["point"], cfg["data"] = [0, 0], {"u_D": ["0", "-delta*t"]}
    one = contact.run_load_path(contact.load_scene({**cfg, "load": {"steps": 1, "cuts": 0}}))
    assert one.converged and one.cuts == [] and one.steps[0].result.predicted is True
    fine = contact.run_load_path(contact.load_scene({**cfg, "load": {"steps": 8}}))
    a, b = one.steps[-1].result.u_h.x.array, fine.steps[-1].result.u_h.x.array
    assert np.max(np.abs(a - b)) <= 1e-8 * np.max(np.abs(b))
    sets = ["mesh.h=0.1", "mesh.h_contact=0.1", "constants.delta=0.5", "load.steps=5"]
    scene = contact.load_scene(ROOT / "configs" / "hyperelastic_cylinder.yaml", sets)
    its = {}
    for predictor in ("none", "auto"):
        path = contact.run_load_path(scene, predictor=predictor)
        assert path.converged
        its[predictor] = sum(s.result.iterations for s in path.steps)
    assert its["auto"] < its["none"]


def test_the_tangent_of_st_venant_kirchhoff_loses_definiteness_in_strong_compression():
    """The block pressed to 50 % in 5 steps.  Neo-Hookean (polyconvex): K_T stays positive
    definite at every step.  St Venant–Kirchhoff: its plate force −P₂₂ peaks between 40 %
    and 45 % compression (the analytic response) and beyond that K_T on the free unknowns
    has negative eigenvalues: at 30 % none, at 50 % some, and the load path says from which
    step (the homogeneous state still solves the equations: the answer stays analytic)."""
    paths = {}
    for law in LAWS:
        cfg = block(law)
        cfg["obstacle"]["point"] = [0, "1 - 0.5*t"]
        paths[law] = contact.run_load_path(
            contact.load_scene({**cfg, "load": {"steps": 5}}), method="fb", keep_all=True
        )
        assert paths[law].converged
    assert [s.negative_eigenvalues for s in paths["neo_hookean"].steps] == [0] * 5
    assert paths["neo_hookean"].indefinite == ""
    forces = [
        -uniaxial_stretch("saint_venant_kirchhoff", E, NU, 1 - c, 2)[1] for c in (0.4, 0.45, 0.5)
    ]
    assert forces[0] > forces[1] > forces[2]  # past the limit point at 45 % and 50 %
    svk = paths["saint_venant_kirchhoff"]
    counts = {round(0.5 * s.time, 6): s.negative_eigenvalues for s in svk.steps}
    assert counts[0.3] == 0 and counts[0.5] > 0
    first = min(s.index for s in svk.steps if s.negative_eigenvalues)
    assert svk.indefinite.startswith(f"K_T not positive definite from step {first} ")
    assert svk.indefinite in svk.stop
    p, _ = nodal_pressure(svk.steps[-1].result)
    assert np.max(np.abs(p / forces[2] - 1)) < 1e-8


def test_small_load_limit_is_linear_elasticity():
    """At delta = 5e-4 (0.1 % of the height of an arch with a flat bottom y = 0.01 x²) finite
    strain is a 1e-3 correction: the hyperelastic laws give the linear model's contact
    force and peak pressure within 0.5 % and the same active nodes (contact width a); the
    difference is no longer round-off (≥ 1e-6: the laws are not the linear one)."""

    def figures(model, law="neo_hookean"):
        scene = contact.load_scene(arch(law, delta=5e-4, model=model, cells=(48, 12), c=0.01))
        r = contact.solve(scene, method="fb")
        assert r.converged
        res = contact_resultants(posed_of(scene), r)
        return r.contact_force, res["peak_pressure"], r.n_active

    F, p0, n = figures("elasticity")
    assert n >= 3
    for law in LAWS:
        F_h, p0_h, n_h = figures("hyperelastic", law)
        assert n_h == n
        assert abs(F_h / F - 1) < 5e-3 and abs(p0_h / p0 - 1) < 5e-3
        assert abs(F_h / F - 1) > 1e-6


def test_small_indentation_of_a_neo_hookean_cylinder_is_the_linear_hertz_scene():
    """configs/hertz_2d.yaml (a cylinder of radius 1 on a plane, quarter model) at
    indentation 0.001 R with the neo-Hookean law: the contact half-width a (the active
    measure) and the peak pressure p0 of the linear scene on the same mesh within 0.5 %
    (measured: a equal, p0 −0.09 %, force −0.06 %).  St Venant–Kirchhoff is left out: its
    stress is nonlinear at first order in the strain (1D: P ≈ E ε (1 + 3ε/2)), and the
    ~1 % strain under the contact moves its p0 by 1.3 %."""
    from contact.output.run_report import active_measure

    sets = [
        "mesh.h=0.2",
        "mesh.h_contact=0.005",
        "mesh.zone=0.15",
        "output.verbose=false",
        "adapt=none",
        "reference=none",
        "constants.delta=0.001",
    ]
    figures = []
    for model in (["model.type=elasticity"], ["model.type=hyperelastic", "model.law=neo_hookean"]):
        scene = contact.load_scene(ROOT / "configs" / "hertz_2d.yaml", sets + model)
        r = contact.solve(scene, method="fb")
        assert r.converged
        p0 = contact_resultants(posed_of(scene), r)["peak_pressure"]
        figures.append((active_measure(r), p0, r.n_active))
    (a, p0, n), (a_h, p0_h, n_h) = figures
    assert n >= 4 and n_h == n
    assert abs(a_h / a - 1) < 5e-3 and abs(p0_h / p0 - 1) < 5e-3
    assert abs(p0_h / p0 - 1) > 1e-6


@pytest.mark.parametrize(
    "change, key",
    [
        ({"model": {"type": "hyperelastic", "E": 1.0}}, "model.law: required"),
        ({"model": {"type": "elasticity", "E": 1.0, "law": "neo_hookean"}}, "model.law: only for"),
        ({"model": {"type": "hyperelastic", "law": "mooney", "E": 1.0}}, "model.law:"),
        (
            {"obstacle": {"type": "plane", "point": [0, "1 - x"], "normal": [0, -1]}},
            "obstacle.point:",
        ),
        (
            {"friction": {"law": "coulomb", "coefficient": 0.3, "coulomb": "fixed_point"}},
            "friction.coulomb: fixed_point",
        ),
        ({"solver": {"method": "fb", "sequence": 2}}, "solver.sequence: grid sequencing"),
        ({"load": {"steps": 2, "cuts": -1}}, "load.cuts:"),
    ],
)
def test_bad_hyperelastic_input_names_the_key(change, key):
    with pytest.raises(ConfigError, match=f"^{key}"):
        contact.load_scene({**block("neo_hookean"), **change})


def test_cli_block_writes_the_force_of_every_step(tmp_path):
    """``contact run configs/hyperelastic_block.yaml``: exit 0, steps.csv's contact force of
    each step is the analytic plate force at λ₂ = 1 − 0.3 t to 1e-8: the whole block on its
    floor, 2 quarters side by side × width 1 × −P₂₂ (the mirror image across the floor
    y = 0, normal to the force, is a second plate pressing upwards: not added), the same in
    summary.json and from contact.csv's pressures; the XDMF series holds u_h for ParaView's
    Warp By Vector; a bad law is exit 2 with one line naming model.law."""
    scene = str(ROOT / "configs" / "hyperelastic_block.yaml")
    proc = cli(tmp_path, "run", scene, "-o", "out", "-q", "--set", "output.png=false")
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader(open(tmp_path / "out" / "steps.csv")))
    assert [float(r["time"]) for r in rows] == pytest.approx([1 / 3, 2 / 3, 1.0])
    assert [r["tangent_negative_eigenvalues"] for r in rows] == ["0"] * 3
    assert all(int(r["newton_iterations"]) <= 8 for r in rows)  # issue 31's bound per step
    for r in rows:
        _, P22 = uniaxial_stretch("neo_hookean", E, NU, 1 - 0.3 * float(r["time"]), 2)
        assert float(r["contact_force"]) == pytest.approx(-2 * P22, rel=1e-8)
        # the force–displacement columns: the plate moved 0.3 t towards the block
        assert float(r["obstacle_approach"]) == pytest.approx(0.3 * float(r["time"]), rel=1e-12)
        assert float(r["prescribed_displacement"]) == 0.0
    assert "u_h" in (tmp_path / "out" / "solution_002.xdmf").read_text()
    info = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert info["symmetric_copies"] == 4 and info["steps"][-1]["contact_force"] == pytest.approx(
        -2 * P22, rel=1e-8
    )
    table = list(csv.DictReader(open(tmp_path / "out" / "contact.csv")))
    x = np.array([float(r["x"]) for r in table])
    p = -np.array([float(r["lambda_n"]) for r in table])  # uniform: the quarter's top, width 1
    assert np.ptp(x) == pytest.approx(1.0) and np.max(np.abs(p / -P22 - 1)) < 1e-8
    assert float(rows[-1]["contact_force"]) == pytest.approx(2 * np.mean(p) * np.ptp(x), 1e-8)
    bad = cli(tmp_path, "run", scene, "-o", "bad", "-q", "--set", "model.law=mooney")
    lines = [ln for ln in bad.stderr.splitlines() if ln.strip()]
    assert bad.returncode == 2 and len(lines) == 1 and "model.law" in lines[0], bad.stderr
    assert not (tmp_path / "bad").exists()


def test_cli_draws_the_force_displacement_curve(tmp_path):
    """A hyperelastic load path writes force.png: the contact force against the obstacle's
    approach (the coarse cylinder, 2 steps; steps.csv's approach is delta·t = 0.2 t)."""
    scene = str(ROOT / "configs" / "hyperelastic_cylinder.yaml")
    sets = ["mesh.h=0.3", "mesh.h_contact=0.05", "load.steps=2", "output.formats=[]"]
    proc = cli(tmp_path, "run", scene, "-o", "out", "-q", *sum((["--set", s] for s in sets), []))
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader(open(tmp_path / "out" / "steps.csv")))
    assert [float(r["obstacle_approach"]) for r in rows] == pytest.approx([0.1, 0.2], rel=1e-12)
    png = (tmp_path / "out" / "force.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 10_000


API_RUN = """
import sys, json
sys.path.insert(0, "tests")
import contact
from test_hyperelastic import arch, tilted_arch
figures = []
for cfg in ({**arch("neo_hookean"), "load": {"steps": 4}}, tilted_arch(0.3, "neo_hookean")):
    path = contact.run_load_path(contact.load_scene(cfg), method="fb")
    r = path.steps[-1].result
    figures += [path.converged, r.contact_force, r.n_active,
                [s.negative_eigenvalues for s in path.steps]]
if r.u_h.function_space.mesh.comm.rank == 0:   # global values (one line: ranks' output may mix)
    print(json.dumps(figures))
"""


@pytest.mark.mpi
def test_api_serial_and_two_ranks_agree(tmp_path):
    """The Python API on the arch's load path and on the tilted plane (rotated unknowns):
    the same contact forces (to 1e-10, the solver stops at |Phi| ~ 1e-14), active nodes and
    tangent stability on 1 and 2 ranks."""
    import json

    from clirun import MPIRUN

    out = {}
    for ranks in (1, 2):
        cmd = [sys.executable, "-c", API_RUN]
        proc = subprocess.run(
            [str(MPIRUN), "-n", str(ranks), *cmd],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        lines = [json.loads(ln) for ln in proc.stdout.splitlines() if ln.startswith("[")]
        assert len(lines) == 1, proc.stdout
        out[ranks] = lines[0]
    for i in (0, 4):  # the two scenes: converged, force, active nodes, negative eigenvalues
        assert out[1][i] and out[2][i]
        assert out[2][i + 1] == pytest.approx(out[1][i + 1], rel=1e-10)
        assert out[2][i + 2 : i + 4] == out[1][i + 2 : i + 4]


def test_a_linear_scene_never_imports_the_hyperelastic_model():
    """Importing contact and running a linear elastic solve leaves contact.models.hyperelastic
    unloaded (the dispatch imports it only for model type hyperelastic)."""
    code = (
        "import sys, contact\n"
        "s = contact.load_scene('configs/block_on_plane.yaml',"
        " ['mesh.cells=[8,2]', 'adapt=none', 'output.verbose=false'])\n"
        "assert contact.solve(s).converged\n"
        "print('contact.models.hyperelastic' in sys.modules)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split()[-1] == "False"


def test_large_indentation_is_the_vi_solution_and_converges_under_refinement():
    """The neo-Hookean cylinder pressed to indentation 0.5 R (configs/hyperelastic_cylinder.yaml
    on a uniform h = 0.1 mesh, 5 steps; the contact width grows to about R): PETSc's
    vinewtonrsls on the same discrete problem (the plane's constraint is a bound; it needs
    step cuts) gives fb's u_h to 1e-8 of max |u_h| and its force at every step both reach;
    the force–indentation curve stiffens (increasing, convex); one uniform refinement moves
    F(0.5 R) by less than 1 % (demos/RESULTS.md §11.3: the study to 4 levels)."""
    from contact import refine

    sets = ["mesh.h=0.1", "mesh.h_contact=0.1", "constants.delta=0.5", "load.steps=5"]
    scene = contact.load_scene(ROOT / "configs" / "hyperelastic_cylinder.yaml", sets)
    fb = contact.run_load_path(scene, method="fb", keep_all=True)
    vi = contact.run_load_path(scene, method="vinewtonrsls", keep_all=True)
    assert fb.converged and vi.converged, (fb.stop, vi.stop)
    by_time = {round(s.time, 12): s for s in vi.steps}
    comm = scene.comm
    for s in fb.steps:
        other = by_time[round(s.time, 12)]
        u, v = s.result.u_h.x.array, other.result.u_h.x.array
        top = comm.allreduce(float(np.max(np.abs(u))), op=MPI.MAX)
        assert comm.allreduce(float(np.max(np.abs(u - v))), op=MPI.MAX) <= 1e-8 * top
        assert other.result.contact_force == pytest.approx(s.result.contact_force, rel=1e-8)
    force = np.r_[0.0, [s.result.contact_force for s in fb.steps]]
    assert np.all(np.diff(force) > 0) and np.all(np.diff(force, 2) > 0)
    n = scene.mesh.topology.index_map(scene.mesh.topology.dim).size_local
    fine, _ = refine(scene, np.arange(n, dtype=np.int32))
    finer = contact.run_load_path(fine, method="fb")
    assert finer.converged
    assert abs(finer.steps[-1].result.contact_force / force[-1] - 1) < 1e-2
