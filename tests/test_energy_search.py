"""The energy line search of hyperelastic bodies (``solver.line_search: energy``, the default
``auto`` there; contact/solvers/energy_search.py, contact/solvers/curvature.py; issue 31).

Checked: the inertia the Newton factorization reads equals the independent count of
:func:`contact.models.hyperelastic.negative_eigenvalues`, and the direction of negative
curvature is an eigenvector of the pencil (A, D) with a negative eigenvalue; where the
tangent is definite the search takes Newton's steps whole (the same solution as plain
Newton, nothing logged); past St Venant–Kirchhoff's material limit plain Newton returns
inverted or unstable equilibria (reported), while the energy search never leaves the
admissible set (det F > 0) and says why it stops; bad input names the key."""

from __future__ import annotations

import csv
import json

import contact
from contact import ConfigError
from contact.models.hyperelastic import min_det_F, uniaxial_stretch
from contact.solvers.curvature import CurvatureSystem
from contact.solvers.newton import Complementarity

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc
from test_hyperelastic import arch, block


def test_the_newton_factorization_counts_the_negative_eigenvalues_and_finds_their_direction(
    monkeypatch,
):
    """The SVK block pressed to 50 % (5 steps, plain Newton: the homogeneous state, past the
    material's limit point): the LDLᵀ factorization of the reduced Newton matrix of min's
    law at the solution has as many negative eigenvalues as the independent count of K_T on
    the free unknowns (> 0); the shift τ D makes it definite; and the inverse iteration's
    v satisfies A v = μ₁ D v (residual ≤ 1e-6 ‖A v‖) with μ₁ < 0, the same v and μ₁ (to
    1e-8, 1e-10) as the iteration run on A_τ gathered onto rank 0."""
    cfg = block("saint_venant_kirchhoff")
    cfg["obstacle"]["point"] = [0, "1 - 0.5*t"]
    scene = contact.load_scene({**cfg, "load": {"steps": 5}})
    path = contact.run_load_path(scene, method="min", line_search="basic")
    step = path.steps[-1]
    r, p = step.result, step.result.problem
    assert path.converged and step.negative_eigenvalues > 0
    system = CurvatureSystem(p, "test_curvature_")
    opts = {
        "ksp_type": "preonly",
        "pc_type": "cholesky",
        "pc_factor_mat_solver_type": "mumps",
        "mat_mumps_icntl_13": 1,
        "mat_mumps_icntl_24": 1,
    }
    db = PETSc.Options()
    for key, value in opts.items():
        db["test_curvature_" + key] = value
    try:
        system.ksp.setFromOptions()
        x = p.b.duplicate()
        p.to_unknowns(r.u_h.x.petsc_vec, x)
        p.linearize(x)
        cp = Complementarity(p)
        p.c = 1.0
        a, b, _ = cp.pair(x)
        system.set_law(*cp.law(a, b, "min", 0.5))
        assert system.negative == step.negative_eigenvalues
        assert system.shift > 0 and system.factorizations >= 2
        v = system.negative_direction()
        assert v is not None and system.curvature < 0
        Av, Dv = v.duplicate(), v.duplicate()
        Dv.pointwiseMult(system.D, v)
        system.A.mult(v, Av)
        Av.axpy(-system.shift, Dv)  # A v = A_τ v − τ D v
        res = Av.copy()
        res.axpy(-system.curvature, Dv)
        assert res.norm() <= 1e-6 * Av.norm()
        # the same iteration on A_τ gathered onto rank 0 (what more than one rank runs)
        vg, mu = system.gathered_direction()
        assert mu == pytest.approx(system.curvature, rel=1e-10)
        vg.axpy(-1.0, v)
        assert vg.norm() <= 1e-8 * v.norm()
        vg.destroy()
        # rank 0's dense inverse failing (np.linalg.inv) is an error on every rank, after the bcast

        def singular(*args):
            raise np.linalg.LinAlgError("Singular matrix")

        with monkeypatch.context() as m:
            m.setattr(np.linalg, "inv", singular)
            with pytest.raises(np.linalg.LinAlgError, match="gathered A_τ"):
                system.gathered_direction()
        for obj in (x, Av, Dv, res):
            obj.destroy()
        cp.destroy()
    finally:
        for key in opts:
            db.delValue("test_curvature_" + key)
        system.destroy()


def test_where_the_tangent_is_definite_the_energy_search_takes_newtons_steps():
    """The neo-Hookean arch pressed in 4 steps (K_T definite throughout): the energy search
    logs nothing, and its solution is plain Newton's (1e-10 of max |u|) with no more
    Newton steps per load step than plain Newton's + 1 (the factorizations differ: LDLᵀ
    against LU, so the last residual may cross the tolerance one step apart)."""
    scene = contact.load_scene({**arch("neo_hookean"), "load": {"steps": 4}})
    paths = {ls: contact.run_load_path(scene, line_search=ls) for ls in ("basic", "energy")}
    assert all(p.converged for p in paths.values())
    energy, basic = paths["energy"].steps, paths["basic"].steps
    assert all(s.result.options["line_search"] == "energy" for s in energy)
    assert all(s.result.tangent_log == [] for s in energy)
    assert paths["energy"].tangent_events == []
    for e, b in zip(energy, basic):
        assert e.result.iterations <= b.result.iterations + 1
    u_e, u_b = energy[-1].result.u_h.x.array, basic[-1].result.u_h.x.array
    scale = scene.comm.allreduce(float(np.max(np.abs(u_b))), op=MPI.MAX)
    assert scene.comm.allreduce(float(np.max(np.abs(u_e - u_b))), op=MPI.MAX) <= 1e-10 * scale


@pytest.mark.parametrize("method", ["fb", "min"])
def test_past_the_material_limit_the_energy_search_keeps_matter_whole(method):
    """The SVK arch pressed 0.18 (36 % of its height) in one step, past the end of its
    stable branch (at about 0.165 on this mesh; 0.16 converges in 5–6 steps either way):
    whatever plain Newton returns is no stable admissible state (measured: fb and min
    converge in 19 and 37 steps to det F = −1.02, inverted cells, reported in the load
    path's notes), while the energy search never returns one either — it stops with every
    iterate admissible (det F > 0) and says so, or (on another CPU) converges to a stable
    admissible equilibrium; should plain Newton's equilibrium keep det F > 0 (another CPU),
    the load path takes it as the equilibrium branch and reports it unstable, with the
    negative eigenvalues of K_T there."""
    cfg = {**arch("saint_venant_kirchhoff", delta=0.18, cells=(8, 4)), "load": {"steps": 1}}
    cfg["load"]["cuts"] = 0
    scene = contact.load_scene(cfg)
    basic = contact.run_load_path(scene, method=method, line_search="basic")
    step = basic.steps[-1]
    if step.result.converged:
        assert step.min_det_F <= 0 or step.negative_eigenvalues > 0
        if step.min_det_F <= 0:
            assert basic.inverted.startswith("step 1 (t = 1) inverts matter (min det F = ")
            assert basic.inverted in basic.stop
    energy = contact.run_load_path(scene, method=method, line_search="energy")
    r = energy.steps[-1].result
    if r.converged:
        step = energy.steps[-1]
        assert step.min_det_F > 0
        assert step.negative_eigenvalues == 0 or energy.branch_steps == [
            (1, 1.0, step.negative_eigenvalues)
        ]
    else:
        assert r.reason == "diverged_line_search"
        assert min_det_F(r) > 0
        assert r.tangent_log[-1]["merit"] == "none"
        assert "no step keeps det F > 0: stopped" in energy.tangent_events[-1]


def test_the_energy_search_needs_an_energy_and_a_factorization():
    """line_search energy on a linear elastic scene, or with an iterative linear solver
    other than CG + GAMG (BiCGStab: no indefiniteness test): one ConfigError naming
    solver.line_search."""
    cfg = {**arch(model="elasticity"), "solver": {"line_search": "energy"}}
    with pytest.raises(ConfigError, match="^solver.line_search: energy needs a body"):
        contact.solve(contact.load_scene(cfg))
    cfg = {**arch(), "solver": {"line_search": "energy", "linear": "bcgs"}}
    with pytest.raises(ConfigError, match="^solver.line_search: energy needs a direct"):
        contact.solve(contact.load_scene(cfg))


#: Euler's load of the strip (configs/hyperelastic_strip.yaml): fixed–guided, effective
#: length L, P_E = π² E' I / L², E' = E / (1 − ν²), I = h³/12 (per unit depth)
STRIP_EULER = np.pi**2 * (1.0 / (1 - 0.3**2)) * 0.05**3 / 12


def test_the_strip_buckles_at_the_step_its_tangent_turns_indefinite(tmp_path):
    """``contact run configs/hyperelastic_strip.yaml`` (SVK, L/h = 20, the wall pushed in
    10 steps to 1.2 δ_E): the energy search meets the indefinite tangent at Newton step 0
    of step 7 (t = 1.04) and no earlier, says so on that step's terminal line and in
    summary.json, and takes a step along the direction of negative curvature: the strip
    buckles (lateral deflection > 0.02 L at t = 1.2) and the force stops rising.  The
    buckling load (the largest force) is Euler's within the P1 mesh's stiffness, 1–6 %
    above (measured 3.2 %; the inertia brackets the discrete load in t ∈ (1.033, 1.034]).
    Plain Newton (line_search basic) finds the same step by the count of negative
    eigenvalues at its solutions and stays straight (deflection < 1e-3 L), its force
    rising past 1.15 P_E: an unstable equilibrium, reported as such."""
    from clirun import ROOT
    from clirun import contact as cli

    scene = ROOT / "configs" / "hyperelastic_strip.yaml"
    proc = cli(tmp_path, "run", str(scene), "-o", "out", "--set", "output.png=false")
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stdout.splitlines() if "K_T indefinite" in ln]
    assert len(lines) == 1 and lines[0].startswith("contact: step 7 t = 1.04: "), lines
    assert "negative-curvature step" in lines[0]
    rows = list(csv.DictReader(open(tmp_path / "out" / "steps.csv")))
    flagged = [float(r["time"]) for r in rows if int(r["indefinite_newton_steps"])]
    assert flagged[0] == 1.04
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["tangent_events"][0].startswith(
        "step 7 (t = 1.04): K_T indefinite at Newton step(s) 0 (up to 1 negative eigenvalue"
    )
    force = np.array([float(r["contact_force"]) for r in rows])
    assert 1.0 <= force.max() / STRIP_EULER <= 1.06
    assert force[-1] <= force[6] * (1 + 1e-3)  # past the buckle the force stops rising
    assert [int(r["tangent_negative_eigenvalues"]) for r in rows] == [0] * len(rows)

    strip = contact.load_scene(scene, ["output.verbose=false"])
    deflection = {}
    for ls in ("basic", "energy"):
        path = contact.run_load_path(strip, line_search=ls)
        assert path.converged
        u = path.steps[-1].result.u_h.x.array.reshape(-1, 2)
        deflection[ls] = strip.comm.allreduce(float(np.max(np.abs(u[:, 1]))), op=MPI.MAX)
        if ls == "basic":
            first = next(s for s in path.steps if s.negative_eigenvalues)
            assert first.time == 1.04 and path.indefinite.startswith(
                "K_T not positive definite from step 7 "
            )
            assert path.steps[-1].result.contact_force / STRIP_EULER > 1.15
    assert deflection["basic"] < 1e-3 and deflection["energy"] > 0.02


# ---------------------------------------------------------------- SVK block past 38 % (issue 39)
def svk_moduli(stretch: float) -> np.ndarray:
    """The incremental moduli A_iJkL = ∂P_iJ/∂F_kL of St Venant–Kirchhoff (E, NU) in the
    homogeneous plane-strain compression of the block to ``stretch`` with free sides
    (F = diag(λ₁, stretch), λ₁ the root of P₁₁ = 0): A = δ_ik S_JL + F_iM C_MJNL F_kN."""
    from contact.models.physics import lame

    mu, lm = lame(1.0, 0.3)
    l1, _ = uniaxial_stretch("saint_venant_kirchhoff", 1.0, 0.3, stretch, 2)
    F, eye = np.diag([l1, stretch]), np.eye(2)
    S = lm * np.trace(0.5 * (F.T @ F - eye)) * eye + mu * (F.T @ F - eye)
    C = lm * np.einsum("ij,kl->ijkl", eye, eye) + mu * (
        np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye)
    )
    return np.einsum("ik,JL->iJkL", eye, S) + np.einsum("iM,MJNL,kN->iJkL", F, C, F)


def free_surface_determinant(stretch: float) -> float:
    """Biot's surface instability of the free side x = 1 (normal e₁; the body x₁ < 1)
    compressed along it: perturbations exp(i k (x₂ + p x₁)) decaying into the body (the two
    roots p of det Q(p) = 0, Q_ik = A_iJkL n_J n_L, n = (p, 1), with Im p < 0) and their
    tractions A_i1kL n_L a_k on the face; the sine of the angle between the two traction
    vectors, 0 where a combination of them is traction free (the surface buckles)."""
    A = svk_moduli(stretch)
    Q = lambda p: np.einsum("iJkL,J,L->ik", A, np.array([p, 1.0]), np.array([p, 1.0]))  # noqa: E731
    coef = np.polyfit(np.arange(5.0), [np.linalg.det(Q(p)) for p in range(5)], 4)
    columns = []
    for p in (r for r in np.roots(coef) if r.imag < 0):
        w, v = np.linalg.eig(Q(p))
        a = v[:, np.argmin(np.abs(w))]
        columns.append(np.einsum("ikL,L,k->i", A[:, 0], np.array([p, 1.0]), a))
    if len(columns) != 2:  # past the loss of ellipticity: no longer two decaying modes
        return np.nan
    M = np.array(columns).T
    return float(abs(np.linalg.det(M)) / np.prod(np.linalg.norm(M, axis=0)))


def strong_ellipticity(stretch: float) -> float:
    """min over unit n of the smallest eigenvalue of the acoustic tensor A_iJkL n_J n_L."""
    A = svk_moduli(stretch)
    angles = np.linspace(0.0, np.pi, 4001)
    n = np.stack([np.cos(angles), np.sin(angles)])
    return float(np.linalg.eigvalsh(np.einsum("iJkL,Jt,Lt->tik", A, n, n))[:, 0].min())


def test_the_svk_block_loses_stability_at_its_free_surface_before_40_percent():
    """Why the SVK block at 40 % compression leaves its homogeneous state: the state is an
    unstable equilibrium there, in the continuum and on the mesh.  Compressed with free
    sides, the free surface loses stability (Biot's surface wrinkling: a traction-free
    decaying mode, the determinant's root) at λ₂ = 0.63602 (36.4 %, t = 0.728 of the 50 %
    path), strong ellipticity is lost at λ₂ = 0.6105 (39.0 %) and the plate force peaks at
    the uniaxial limit point λ₂ = 1/√3 (42.3 %, beyond 40 %).  The discrete tangent at the
    homogeneous state (plain Newton's solution: exact on P1) is positive definite at the
    surface instability's t on 4 × 4 and 8 × 8 cells — a conforming discretization can only
    lose stability later —, indefinite at t = 0.8 (40 %) on both, and its onset moves
    towards the continuum's under refinement (8 × 8 indefinite at t = 0.75, 4 × 4 not;
    measured onsets: 4 × 4 in (0.7766, 0.7781], 8 × 8 (0.74, 0.75], 16 × 16 (0.73, 0.735],
    32 × 32 and 64 × 64 (0.725, 0.73])."""
    grid = np.linspace(0.615, 0.7, 851)
    s0 = grid[int(np.nanargmin([free_surface_determinant(s) for s in grid]))]
    lo, hi = s0 - 1e-4, s0 + 1e-4
    for _ in range(80):  # golden section on the determinant's |root|
        a, b = lo + 0.382 * (hi - lo), lo + 0.618 * (hi - lo)
        lo, hi = (lo, b) if free_surface_determinant(a) < free_surface_determinant(b) else (a, hi)
    surface = 0.5 * (lo + hi)
    assert free_surface_determinant(surface) < 1e-9  # a root, not a near miss
    assert surface == pytest.approx(0.63602, abs=1e-5)
    assert free_surface_determinant(0.7) > 0.1 and free_surface_determinant(0.8) > 0.1
    assert strong_ellipticity(0.62) > 0 > strong_ellipticity(0.61)
    # force P₂₂ ∝ λ(λ² − 1): its extremum 1/√3 comes last
    assert surface > 0.61 > 1 / np.sqrt(3) and 1 - 1 / np.sqrt(3) > 0.4
    t_surface = (1 - surface) / 0.5
    times = [0.2, 0.4, 0.6, round(t_surface, 6), 0.75, 0.8]
    counts = {}
    for cells in (4, 8):
        cfg = block("saint_venant_kirchhoff")
        cfg["mesh"]["cells"] = [cells, cells]
        cfg["obstacle"]["point"] = [0, "1 - 0.5*t"]
        scene = contact.load_scene({**cfg, "load": {"times": times}})
        path = contact.run_load_path(scene, line_search="basic", keep_all=True)
        assert path.converged
        l1, _ = uniaxial_stretch("saint_venant_kirchhoff", 1.0, 0.3, 0.6, 2)
        u = path.steps[-1].result.u_h
        X = u.function_space.tabulate_dof_coordinates()[:, :2]
        assert np.max(np.abs(u.x.array.reshape(-1, 2) - X * [l1 - 1, -0.4])) < 1e-10
        counts[cells] = [s.negative_eigenvalues for s in path.steps[3:]]
    assert counts[4][0] == 0 and counts[8][0] == 0  # at the continuum's onset: stable
    assert counts[4][1] == 0 < counts[8][1]  # t = 0.75: the finer mesh is past its onset
    assert counts[4][2] > 0 and counts[8][2] > 0  # t = 0.8 (40 %): unstable on both


@pytest.mark.parametrize("ranks", [0, pytest.param(2, marks=pytest.mark.mpi)])
def test_the_svk_block_at_50_percent_follows_its_equilibrium_branch(tmp_path, ranks):
    """``contact run configs/hyperelastic_block.yaml`` with St Venant–Kirchhoff to 50 % in
    5 steps (default solver): at step 4 (t = 0.8, 40 %) the homogeneous state is unstable
    (above): the energy search leaves it and finds no stable equilibrium that keeps
    det F > 0; the load path then takes the equilibrium branch by plain Newton, says so in
    one line naming the step and the negative eigenvalue count of K_T there (1), lists it
    in summary.json (``bifurcation``, ``equilibrium_branch``) and finishes: exit 0, every
    step's plate force the analytic homogeneous one (1e-8), nothing on stderr; the same on
    2 ranks (every decision on the branch is collective)."""
    from clirun import ROOT
    from clirun import contact as cli

    scene = ROOT / "configs" / "hyperelastic_block.yaml"
    sets = ["model.law=saint_venant_kirchhoff", "constants.compression=0.5", "load.steps=5"]
    args = [a for item in [*sets, "output.png=false"] for a in ("--set", item)]
    proc = cli(
        tmp_path,
        "run",
        str(scene),
        "-o",
        "out",
        "-q",
        *args,
        ranks=ranks,
        env={"PYTHONWARNINGS": ""},
    )
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    lines = [ln for ln in proc.stdout.splitlines() if "equilibrium branch" in ln]
    assert len(lines) == 2 and len(lines[0]) <= 300, proc.stdout
    assert lines[0].startswith("contact: step 4 (t = 0.8): the energy search found no stable")
    assert lines[0].endswith("unstable, K_T has 1 negative eigenvalue(s) there")
    assert lines[1].startswith("contact: step 5 (t = 1): on the equilibrium branch")
    assert "no step keeps det F > 0" not in proc.stdout
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["converged"] is True and summary["bifurcation"] == lines[0][9:]
    assert [(b["step"], b["negative_eigenvalues"] > 0) for b in summary["equilibrium_branch"]] == [
        (4, True),
        (5, True),
    ]
    assert summary["equilibrium_branch"][0]["negative_eigenvalues"] == 1
    for row in csv.DictReader(open(tmp_path / "out" / "steps.csv")):
        _, P22 = uniaxial_stretch(
            "saint_venant_kirchhoff", 1.0, 0.3, 1 - 0.5 * float(row["time"]), 2
        )
        assert float(row["contact_force"]) == pytest.approx(-2 * P22, rel=1e-8)
        assert float(row["min_det_F"]) > 0
