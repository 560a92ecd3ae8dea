"""Coulomb and Tresca friction between two hyperelastic bodies coupled on the current
configuration (contact/drivers/recouple.py): the slips measured against the previous load
step's converged state through the current coupling, the tangents of the current coupling,
Coulomb's bound F λ_n from the current pressure.  Checks: the small-load limit against the
small-strain Cattaneo–Mindlin run of the same mesh (the gap closing with the load), a block
dragged over another into full slip (Σ w|λ_t| = F Σ w|λ_n| over the slipping nodes, action =
reaction, serial = 2 ranks; and in 3D), a re-coupled solve starting from its guess, Tresca's
bound, the 3D finite-strain patch test with friction."""

from pathlib import Path

import contact
from contact.post.reference import compare
from contact.solvers import owned_residual

import numpy as np
import pytest
from test_bodies import run as run_script
from test_hyperelastic_bodies import PATCH_3D, PATCH_3D_FINITE, P, interface_force, uniaxial

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "tests" / "hyperelastic_friction_run.py"
CATTANEO = ROOT / "configs" / "two_body_cattaneo_2d.yaml"
DRAG = ROOT / "configs" / "hyperelastic_two_body_drag_2d.yaml"
HYPERELASTIC = ["model.type=hyperelastic", "model.law=neo_hookean"]
F = 0.3  # both scenes' Coulomb coefficient
#: the Cattaneo scene at its own interference (0.1 of R_c = 8) and at a quarter of it, with
#: P the normal force that interference gives (measured on the small-strain run)
LOADS = {
    "overlap 0.1": ["mesh.h_contact=0.05"],
    "overlap 0.025": [
        "mesh.h_contact=0.025",
        "mesh.zone=0.4",
        "mesh.overlap=0.025",
        "constants.P=0.9683",
    ],
}
SLIP = 2


def cattaneo_path(model: list[str], load: list[str]) -> list[dict]:
    """The Cattaneo scene's tangential steps (t = 0.625, 0.75, 0.875): per step the slave
    nodes' status and multipliers (sorted by reference coordinate), the comparison with
    Cattaneo–Mindlin and the couplings."""
    scene = contact.load_scene(CATTANEO, ["output.verbose=false", *load, *model])
    path = contact.run_load_path(scene, verbose=False, keep_all=True)
    assert path.converged and len(path.steps) == 4
    out = []
    for step in path.steps[1:]:
        r = step.result
        p, fr = r.problem, r.friction
        on = slice(0, p.data.pair_nodes)
        X = p.V.tabulate_dof_coordinates()[p.constraint.dofs[on] // 2, :2]
        order = np.lexsort(X.T[::-1])
        out.append(
            {
                "X": X[order],
                "status": fr["status"][on][order],
                "lambda_n": fr["lambda_n"][on][order],
                "values": compare(step.posed, r).values,
                "couplings": getattr(r, "couplings", None),
            }
        )
    return out


@pytest.fixture(scope="module")
def cattaneo():
    """Small strain and neo-Hookean, at both loads."""
    return {
        load: (cattaneo_path([], overrides), cattaneo_path(HYPERELASTIC, overrides))
        for load, overrides in LOADS.items()
    }


def test_small_load_coulomb_is_the_small_strain_partial_slip(cattaneo):
    """Same stick and slip nodes; the tangential force Q = |Σ w λ_t| and the pressures
    within 2 % and 3 % at the scene's load (the strain near the contact ~ 3 %), and both
    gaps at least 1.8× smaller at a quarter of the interference (the strain halves: the
    difference is first order in it; measured 2.3–2.6×); the stick zone against
    Cattaneo–Mindlin's c/a as close as the small-strain run's."""
    gaps = {}
    for load, (linear, finite) in cattaneo.items():
        rows = []
        for lin, fin in zip(linear, finite, strict=True):
            assert np.allclose(lin["X"], fin["X"], atol=1e-12)
            assert np.array_equal(lin["status"], fin["status"])
            assert np.sum(lin["status"] == SLIP) >= 2  # partial slip
            q_lin, q_fin = lin["values"]["tangential_force"], fin["values"]["tangential_force"]
            dq = abs(q_fin / q_lin - 1)
            dn = np.max(np.abs(fin["lambda_n"] - lin["lambda_n"])) / np.max(np.abs(lin["lambda_n"]))
            rows.append((dq, dn))
            c_lin, c_fin = lin["values"]["c_error"], fin["values"]["c_error"]
            assert abs(c_fin) <= abs(c_lin) + 0.02
        gaps[load] = np.max(rows, axis=0)
    big, small = gaps["overlap 0.1"], gaps["overlap 0.025"]
    assert big[0] < 0.02 and big[1] < 0.03
    assert np.all(big / small >= 1.8)


def test_recoupled_frictional_solves_start_from_their_guess(cattaneo):
    """Each re-coupling of a load step starts from the previous coupling's solution with the
    step's friction history (the previous load step's state): a few Newton steps, not a
    restart of the step (10–30 each before, every one from the step's cold ‖Φ‖)."""
    for _, finite in cattaneo.values():
        for step in finite:
            log = step["couplings"]
            assert 3 <= len(log) <= 12
            assert all(row["newton"] <= 3 for row in log[1:])
            assert all(row["first"] < 0.1 * log[0]["first"] for row in log[2:])


def drag_checks(res: dict) -> None:
    """Full slip from t = 0.3 on: every slave node slips, Σ w|λ_t| / Σ w|λ_n| = F to 1e-8;
    the slave's internal force is the master's reversed to round-off; couplings and Newton
    steps per load step bounded."""
    assert res["converged"]
    steps = res["steps"]
    t, converged, couplings, newton, stick, slip, separated, ratio = steps[:, :8].T
    slave, master = steps[:, 8:10], steps[:, 10:12]
    assert np.all(converged == 1)
    assert stick[0] > slip[0] > 0  # pressed: the corners slip
    full = t >= 0.3 - 1e-12
    assert np.all(stick[full] == 0) and np.all(separated[full] == 0) and np.all(slip[full] > 10)
    assert np.all(np.abs(ratio[full] / F - 1) <= 1e-8)
    assert np.all(np.abs(slave + master) <= 1e-12 * np.abs(slave[:, 1:]))
    assert np.all(np.abs(slave[full, 0]) > 0.25 * F * slave[full, 1])  # it drags
    assert np.all(couplings <= 15) and np.all(newton <= 30)


@pytest.fixture(scope="module")
def drag(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("drag")
    return [
        run_script(tmp, DRAG, n, "load={times: [0.2, 0.3, 0.4]}", script=SCRIPT) for n in (1, 2)
    ]


def test_a_block_dragged_over_another_slides_at_the_coulomb_bound(drag):
    drag_checks(drag[0])


@pytest.mark.mpi
def test_the_dragged_block_on_two_ranks_is_the_serial_one(drag):
    s, p = drag
    drag_checks(p)
    assert np.array_equal(s["steps"][:, :7], p["steps"][:, :7])  # counts
    assert np.allclose(s["steps"][:, 7:], p["steps"][:, 7:], rtol=0, atol=1e-8 * 0.07)
    assert np.allclose(s["nodes"][:, :2], p["nodes"][:, :2], atol=1e-14)
    scale = np.max(np.abs(s["nodes"][:, 2:]))
    assert np.max(np.abs(s["nodes"][:, 2:] - p["nodes"][:, 2:])) <= 1e-8 * scale


def test_tresca_between_hyperelastic_bodies_slides_at_its_threshold():
    """Tresca's bound s = 0.015 (below F × the pressure, ~0.02): in full slip |λ_t| = s at
    every slave node."""
    s = 0.015
    scene = contact.load_scene(
        DRAG,
        [
            "output.verbose=false",
            "friction.law=tresca",
            "friction.coefficient=null",
            f"friction.threshold={s}",
            "load={times: [0.2, 0.3]}",
        ],
    )
    path = contact.run_load_path(scene, verbose=False)
    assert path.converged
    r = path.steps[-1].result
    fr, on = r.friction, slice(0, r.problem.data.pair_nodes)
    assert np.all(fr["status"][on] == SLIP)
    assert np.max(np.abs(np.linalg.norm(fr["lambda_t"][on], axis=1) / s - 1)) <= 1e-8


#: the dragged block in 3D: the 2D scene extruded along z (the upper block half as deep as
#: the lower one), dragged by 0.3 along x
DRAG_3D = [
    "mesh.blocks=[{corners: [[-1, 0, -0.5], [1, 0.5, 0.5]], cells: [8, 2, 4]},"
    " {corners: [[-0.5, 0.5, -0.25], [0.5, 1, 0.25]], cells: [5, 3, 3]}]",
    'data.u_D=["drag*max(t - 0.2, 0)/0.8*(y > 0.75)", "-delta*min(t/0.2, 1)*(y > 0.75)", "0"]',
    "constants.drag=0.3",
    "load={times: [0.2, 0.4]}",
    "output.verbose=false",
]


def test_a_block_dragged_over_another_in_3d_slides_at_the_coulomb_bound():
    """Two tangents per node: pressed, the rim slips and the middle sticks; dragged, every
    slave node slips with Σ w|λ_t| = F Σ w|λ_n| to 1e-8; action = reaction."""
    scene = contact.load_scene(DRAG, DRAG_3D)
    path = contact.run_load_path(scene, verbose=False, keep_all=True)
    assert path.converged and len(path.steps) == 2
    for k, step in enumerate(path.steps):
        r = step.result
        fr, on = r.friction, slice(0, r.problem.data.pair_nodes)
        status, w = fr["status"][on], fr["w"][on]
        slip = status == SLIP
        assert np.sum(slip) > 0 and (np.all(slip) if k == 1 else np.sum(status == 1) > 0)
        t_sum = np.sum(w[slip] * np.linalg.norm(fr["lambda_t"][on][slip], axis=1))
        n_sum = np.sum(w[slip] * np.abs(fr["lambda_n"][on][slip]))
        assert abs(t_sum / n_sum / F - 1) <= 1e-8
        slave = interface_force(r, step.scene, "slave")
        master = interface_force(r, step.scene, "master")
        assert np.max(np.abs(slave + master)) <= 1e-12 * abs(slave[1])
    assert abs(slave[0]) > 0.25 * F * slave[1]  # dragged along x


def test_the_3d_finite_strain_patch_with_coulomb_friction_stays_exact():
    """The 3D patch (two non-matching neo-Hookean blocks, 17 % compression) with Coulomb
    friction: the two blocks stretch alike, nothing slips, λ_t = 0 and the pressure is the
    exact Cauchy traction at every slave node to 1e-8."""
    overrides = [*PATCH_3D_FINITE, "friction.law=coulomb", f"friction.coefficient={F}"]
    scene = contact.load_scene(PATCH_3D, ["output.verbose=false", "solver.method=min", *overrides])
    path = contact.run_load_path(scene, verbose=False)
    assert path.converged
    r = path.steps[-1].result
    p, fr = r.problem, r.friction
    on = slice(0, p.data.pair_nodes)
    l1, _ = uniaxial(3)
    pressure = p.pressure(owned_residual(r))[on]
    assert np.max(np.abs(pressure * l1**2 / P - 1)) <= 1e-8
    assert np.all(fr["status"][on] == 1)
    assert np.max(np.abs(fr["lambda_t"][on])) <= 1e-10 * P
