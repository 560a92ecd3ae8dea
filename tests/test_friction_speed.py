"""Friction at the cost of frictionless contact (issue 29, item 2): the reduced block system
solved by GMRES + GAMG (``solver.linear: gmres``, contact/solvers/block_system.py) gives
the answers of MUMPS on the assembled H = B K + D (the old path, ``direct``); grid
sequencing of frictional load steps (the first from u = 0, later ones with the previous
step's displacement carried to the coarse meshes) and the secant predictor of load paths
end where the unsequenced, unpredicted path does; the Coulomb fixed point (an independent
algorithm) agrees with the new path."""

import contact
from contact.base.errors import ConfigError
from contact.drivers.load_path import extrapolate
from contact.setup.build import build_problem
from contact.setup.run import run_load_path
from contact.solvers.block_system import BlockReducedSystem
from contact.solvers.friction import FrictionalComplementarity

import numpy as np
import pytest
from dolfinx import fem
from test_friction import BOX, block, clear_of_kinks, coulomb

#: partial slip of the pulled block (stick in the middle, slip at both ends)
PARTIAL = [*coulomb(0.3), 'data.u_D=["0.004", "-0.01"]']
#: a rel. tolerance of answers from different linear solvers: Newton stops at ‖Φ‖ ≤ 1e-12 of
#: the data's scale, the Krylov solves stop at 1e-10 relative (both far below this)
RTOL = 1e-8


def _close(a: np.ndarray, b: np.ndarray, rtol: float = RTOL) -> bool:
    return float(np.max(np.abs(a - b))) <= rtol * float(np.max(np.abs(a)))


@pytest.mark.parametrize(
    "method,form,law",
    [
        ("min", "hsw", "coulomb"),
        ("fb", "projection", "coulomb"),
        ("min", "projection", "tresca"),
        ("blend", "hsw", "coulomb"),
    ],
)
def test_gmres_block_system_equals_mumps_2d(method, form, law):
    sets = (
        [*PARTIAL, f"friction.form={form}"]
        if law == "coulomb"
        else ["friction.law=tresca", "friction.threshold=0.004", 'data.u_D=["0.004", "-0.01"]']
    )
    ref = contact.solve(block(*sets), method=method, linear="direct")
    new = contact.solve(block(*sets), method=method, linear="gmres")
    assert ref.converged and new.converged
    assert ref.linear == "direct" and new.linear == "gmres" and new.krylov_iterations > 0
    assert {1, 2} <= set(ref.friction["status"].tolist())  # stick and slip: both row kinds
    assert _close(ref.u_h.x.array, new.u_h.x.array)
    lam = ref.friction["lambda_t"]
    assert _close(lam, new.friction["lambda_t"])
    clear = clear_of_kinks(ref.friction)
    assert np.array_equal(ref.friction["status"][clear], new.friction["status"][clear])


@pytest.mark.parametrize("form", ["hsw", "projection"])
def test_gmres_block_system_equals_mumps_3d(form):
    """3D: two tangential unknowns, the slip rows' 2 × 2 blocks not symmetric (HSW)."""
    ref = contact.solve(contact.load_scene(BOX, [f"friction.form={form}"]), linear="direct")
    new = contact.solve(contact.load_scene(BOX, [f"friction.form={form}"]), linear="gmres")
    assert ref.converged and new.converged and new.linear == "gmres"
    status = ref.friction["status"]
    assert (status == 1).sum() > 20 and (status == 2).sum() > 20
    assert _close(ref.u_h.x.array, new.u_h.x.array)
    # GAMG is set up for every Newton step's A (block_system.py: BlockReducedSystem.LAG)
    assert new.krylov_log and all(entry["setups"] >= 1 for entry in new.krylov_log)
    if form == "hsw":  # the lagged hierarchy (the old default) reaches the same answer
        lag = {"reduced_lag_pc": True}
        old = contact.load_scene(BOX, [f"friction.form={form}"])
        lagged = contact.solve(old, linear="gmres", petsc_options=lag)
        assert lagged.converged and _close(ref.u_h.x.array, lagged.u_h.x.array)


def test_gmres_path_agrees_with_the_coulomb_fixed_point():
    """The new path against an independent algorithm (a sequence of Tresca problems, each
    by MUMPS)."""
    new = contact.solve(block(*PARTIAL), linear="gmres")
    fp = contact.solve(block(*PARTIAL, "friction.coulomb=fixed_point"), linear="direct")
    assert new.converged and fp.converged and fp.friction["fixed_point_iterations"] > 2
    assert _close(new.u_h.x.array, fp.u_h.x.array)


def test_block_reduction_fixes_stick_and_active_rows():
    """The reduced system of a Jacobian at the solution: every sticking tangential row and
    every active normal row of min is fixed (its unknown is F_i / D_ii), the rows of the
    other nodes stay; A y = r gives the step of H y = F."""
    scene = block(*PARTIAL)
    problem = build_problem(scene)
    r = contact.solve(scene, problem=problem, method="min", linear="direct")
    cp = FrictionalComplementarity(problem)
    x = problem.b.duplicate()
    problem.to_unknowns(r.u_h.x.petsc_vec, x)
    system = BlockReducedSystem(problem, cp.matrix(), "blocktest_")
    system.ksp.setType("gmres")
    system.ksp.setTolerances(rtol=1e-12, max_it=2000)
    system.set_options()
    blocks = cp.block_jacobian(x, system.H, "min", 0.5)
    system.set_block(*blocks)
    status, fs = r.friction["status"], cp.fs
    clear = clear_of_kinks(r.friction)
    stick = clear & (status == 1)
    assert stick.sum() > 5 and (clear & (status == 2)).sum() > 5
    assert np.all(system.fixed[fs.tangent[stick, 0]])
    assert np.all(system.fixed[cp.dofs[clear & (status > 0)]])  # min's active normal rows
    assert not np.any(system.fixed[fs.tangent[clear & (status == 2), 0]])
    F, y, Hy = (problem.b.duplicate() for _ in range(3))
    F.array[:] = np.random.default_rng(0).normal(size=F.getLocalSize())
    system.solve(F, y)
    system.H.mult(y, Hy)
    assert np.linalg.norm(Hy.array - F.array) <= 1e-8 * np.linalg.norm(F.array)
    system.destroy()
    for obj in (F, y, Hy, x):
        obj.destroy()


def test_extrapolate_is_exact_for_a_linear_path():
    scene = block()
    V = fem.functionspace(scene.mesh, ("Lagrange", 1, (2,)))
    u1, u2 = fem.Function(V), fem.Function(V)
    X = V.tabulate_dof_coordinates()[:, 0].repeat(2)
    u1.x.array[:] = 0.3 * X
    u2.x.array[:] = 0.5 * X  # t = 0.3, 0.5: u = t X
    assert np.allclose(extrapolate(u2, u1, 0.8, 0.5, 0.3).x.array, 0.8 * X)
    other = fem.Function(fem.functionspace(block("mesh.cells=[8,2]").mesh, ("Lagrange", 1, (2,))))
    assert extrapolate(u2, other, 0.8, 0.5, 0.3) is None  # another mesh


def test_bad_predictor_is_a_config_error():
    with pytest.raises(ConfigError, match="load.predictor"):
        block("load.steps=2", "load.predictor=quadratic")


#: the pulled block of friction_block_2d on 64 × 16 cells (2210 DoFs), 4 steps: pressed, then
#: dragged into partial and growing slip
PATH = [
    "mesh.cells=[64,16]",
    "load=none",
    "load={times: [0.2, 0.4, 0.6, 0.8]}",
    "output.verbose=false",
]


def _path(*sets: str):
    scene = contact.load_scene("configs/friction_block_2d.yaml", [*PATH, *sets])
    return run_load_path(scene, keep_all=True)


def test_sequenced_and_predicted_load_path_equals_the_plain_one():
    """Every step sequenced (two coarse levels, the history carried to them) with GMRES, or
    cold and unpredicted with MUMPS: the same displacement and tractions at every step."""
    plain = _path("solver.sequence=off", "solver.linear=direct", "load.predictor=none")
    fast = _path("solver.sequence=2", "solver.linear=gmres")
    assert plain.converged and fast.converged
    for a, b in zip(plain.steps, fast.steps):
        assert len(b.result.sequence) == 2 and not a.result.sequence
        assert _close(a.result.u_h.x.array, b.result.u_h.x.array)
        lam_t = a.result.friction["lambda_t"]
        assert _close(lam_t, b.result.friction["lambda_t"])
    statuses = {int(v) for s in plain.steps for v in s.result.friction["status"]}
    assert {1, 2} <= statuses


def test_predictor_path_equals_the_warm_started_one():
    """Unsequenced steps from the secant predictor or the previous solution: same answers."""
    warm = _path("solver.sequence=off", "load.predictor=none")
    pred = _path("solver.sequence=off")
    assert warm.converged and pred.converged
    assert [s.result.predictor is not None for s in pred.steps] == [False, False, True, True]
    for a, b in zip(warm.steps, pred.steps):
        assert _close(a.result.u_h.x.array, b.result.u_h.x.array)


@pytest.mark.parametrize("method", ["fb", "min"])
def test_gmres_on_a_frictionless_scene_agrees_with_vinewtonrsls(method):
    """``solver.linear: gmres`` on a diagonal law (GMRES + GAMG on the assembled H) against
    PETSc's VI solver: the same solution."""
    scene = contact.load_scene(
        "configs/signorini_square.yaml", ["mesh.cells=[24,24]", "output.verbose=false"]
    )
    vi = contact.solve(scene, method="vinewtonrsls", linear="direct", sequence="off")
    r = contact.solve(scene, method=method, linear="gmres", sequence="off")
    assert vi.converged and r.converged and r.linear == "gmres"
    assert _close(vi.u_h.x.array, r.u_h.x.array)
