"""Contact pairs with P2 displacements: the mortar coupling with the quadratic dual basis of
the slave segments (2D) and of the transformed basis of the slave triangles (3D;
contact/models/overlap.py).  The contact patch test with non-matching meshes (2D and 3D,
small and finite strain, serial and 2 ranks), two cylinders against Hertz beside P1 on the
same mesh, action = reaction, and Coulomb and Tresca friction on the 3D frictional patch
(P1 and P2 alike, serial and 2 ranks through the command line)."""

import contact
from contact.models.hyperelastic import negative_eigenvalues
from contact.models.mortar import master_pressure, part_facets, surface_facets
from contact.models.overlap import trace_weights
from contact.post.interface import resultants
from contact.post.reference import compare
from contact.setup.build import build_problem
from contact.setup.posed import posed_of
from contact.solvers import owned_residual

import numpy as np
import pytest
from clirun import run_scene
from scene_runs import read_folder
from test_bodies import COARSE_2D, HERTZ_2D, PATCH_2D, PATCH_3D, ROOT, P, check_patch_2d, run
from test_hyperelastic_bodies import PATCH_2D as FINITE_PATCH_2D
from test_hyperelastic_bodies import PATCH_3D_FINITE, interface_force, uniaxial
from test_hyperelastic_bodies import P as FINITE_P
from test_hyperelastic_bodies import run as run_finite

P2 = ["mesh.degree=2", "output.verbose=false"]
FRICTION_PATCH_3D = ROOT / "configs" / "two_body_friction_patch_3d.yaml"
HYPERELASTIC = ["model.type=hyperelastic", "model.law=neo_hookean"]
STICK, SLIP = 1, 2  # friction statuses (contact.solvers.newton)


@pytest.fixture(scope="module")
def patch():
    scene = contact.load_scene(PATCH_2D, P2)
    return scene, build_problem(scene)


@pytest.mark.parametrize("method", ["fb", "min", "vinewtonrsls"])
def test_p2_patch_pressure_is_exact_at_every_slave_node(patch, method):
    """31 against 10 interface cells, two materials, P2: λ_i = −p at all 63 slave nodes
    (vertices and midpoints) and λ^m_j = −p at all 21 master nodes to 1e-8 relative, the
    interface forces balance and the contact force is p × width."""
    scene, problem = patch
    check_patch_2d(scene, problem, method, slave=63, master=21)


@pytest.mark.mpi
def test_p2_patch_on_two_ranks_equals_serial(tmp_path):
    args = ["--methods=fb,vinewtonrsls", "--set=mesh.degree=2"]
    s, p = run(tmp_path, PATCH_2D, 1, *args), run(tmp_path, PATCH_2D, 2, *args)
    for method in ("fb", "vinewtonrsls"):
        for res in (s, p):
            assert res[f"{method}/info"][0] == 1 and len(res[f"{method}/lambda"]) == 63
            assert np.max(np.abs(res[f"{method}/lambda"] + P)) <= 1e-8 * P
            assert np.max(np.abs(res[f"{method}/lambda_master"] + P)) <= 1e-8 * P
            assert res[f"{method}/info"][4] < 1e-10  # action = reaction
        assert np.allclose(s[f"{method}/Xs"], p[f"{method}/Xs"], atol=1e-14)
        assert np.max(np.abs(s[f"{method}/u"] - p[f"{method}/u"])) <= 1e-8 * np.max(
            np.abs(s[f"{method}/u"])
        )


def test_p2_finite_strain_patch_is_the_exact_cauchy_traction():
    """The neo-Hookean patch (non-matching, re-coupled on the current configuration), P2:
    every slave node's pressure is P/λ₁ to 1e-8, u = (λ − 1) X at every node, the slave
    and master surface forces cancel."""
    scene = contact.load_scene(FINITE_PATCH_2D, P2)
    run_ = contact.run_load_path(scene, verbose=False)
    assert run_.converged
    r = run_.steps[-1].result
    assert r.couplings[-1]["change"] <= 1e-12
    l1, l2 = uniaxial(2)
    p = r.problem
    pressure = p.pressure(owned_residual(r))[: p.data.pair_nodes]
    assert len(pressure) == 63
    assert np.max(np.abs(pressure * l1 / FINITE_P - 1)) <= 1e-8
    X = p.V.tabulate_dof_coordinates()[:, :2]
    u = r.u_h.x.array.reshape(-1, 2)
    assert np.max(np.abs(u - X * np.r_[l1 - 1, l2 - 1])) <= 1e-8 * (1 - l2)
    slave, master = interface_force(r, scene, "slave"), interface_force(r, scene, "master")
    assert abs(slave[-1] - FINITE_P) <= 1e-10 * FINITE_P
    assert abs(slave[-1] + master[-1]) <= 1e-12 * FINITE_P


@pytest.mark.mpi
def test_p2_finite_strain_patch_on_two_ranks_equals_serial(tmp_path):
    s = run_finite(tmp_path, FINITE_PATCH_2D, 1, "mesh.degree=2")
    p = run_finite(tmp_path, FINITE_PATCH_2D, 2, "mesh.degree=2")
    l1, _ = uniaxial(2)
    for res in (s, p):
        assert res["converged"] and len(res["pressure"]) == 63
        assert np.max(np.abs(res["pressure"] * l1 / FINITE_P - 1)) <= 1e-8
    assert np.allclose(s["X"], p["X"], atol=1e-14)
    assert abs(s["force"] - p["force"]) <= 1e-12 * abs(s["force"])


def facet_mean_pressure_error(scene, r) -> float:
    """max over the slave facets within 0.8 a of the centre of |p̄_F − p̄_F^Hertz| / p0:
    p̄_F = Σ_a p_a ∫_F φ_a / |F| the facet's mean pressure (the force it carries over its
    length), p̄_F^Hertz the mean of Hertz's p0 √(1 − x²/a²) over the facet (a and p0 of the
    computed force).  Serial."""
    p = r.problem
    V, bs = p.V, p.V.dofmap.index_map_bs
    pressure = np.zeros(len(V.tabulate_dof_coordinates()))
    pressure[p.output.map // bs] = -r.lmbda_h.x.array
    facets = surface_facets(V, part_facets(scene.boundary, "slave"))
    ref = compare(posed_of(scene), r).values
    a, p0 = ref["hertz_a"], ref["hertz_p0"]
    share = trace_weights(facets.nodes.shape[1], 2)
    x0, x1 = facets.X[:, 0, 0], facets.X[:, 1, 0]
    inside = np.maximum(np.abs(x0), np.abs(x1)) < 0.8 * a
    g, w = np.polynomial.legendre.leggauss(20)
    x = 0.5 * (x0 + x1)[:, None] + 0.5 * (x1 - x0)[:, None] * g
    hertz = 0.5 * (p0 * np.sqrt(1 - (x / a) ** 2)) @ w
    mean = pressure[facets.nodes] @ share
    return float(np.max(np.abs(mean - hertz)[inside]) / p0)


def test_p2_cylinders_carry_hertz_pressure_closer_than_p1_on_the_same_mesh():
    """Two cylinders (R_c = 8, h_contact = 0.1 over a ≈ 0.47): the facets' mean pressure
    within 0.16 % of Hertz's with P2, 0.68 % with P1 (the largest facet error over
    |x| < 0.8 a), action = reaction to round-off.  The nodal pressures of P2 alternate
    between vertices and midpoints (the straight facets' kinks; docs/guide/two-bodies.md), so
    the facet means are the compared figure."""
    errors = {}
    for degree in (1, 2):
        scene = contact.load_scene(HERTZ_2D, [*COARSE_2D, f"mesh.degree={degree}"])
        r = contact.solve(scene, method="min", verbose=False)
        assert r.converged
        assert resultants(posed_of(scene), r)["interface_balance_error"] < 1e-10
        errors[degree] = facet_mean_pressure_error(scene, r)
    assert errors[2] < 0.5 * errors[1] and errors[2] < 0.003


@pytest.mark.mpi
def test_p2_cylinders_serial_equals_two_ranks(tmp_path):
    check_cylinders_serial_equals_two_ranks(tmp_path, [*COARSE_2D, "mesh.degree=2"])


def check_cylinders_serial_equals_two_ranks(tmp_path, overrides: list[str]) -> None:
    """The Hertz cylinders with ``overrides``, method min, on 1 and 2 ranks: the same active
    set, coordinates, displacements and pressures (to 1e-8), action = reaction on both."""
    args = ["--methods=min", *(f"--set={o}" for o in overrides)]
    s, p = run(tmp_path, HERTZ_2D, 1, *args), run(tmp_path, HERTZ_2D, 2, *args)
    assert s["min/info"][0] == p["min/info"][0] == 1
    assert min(s["min/info"][5], p["min/info"][5]) >= 1e-6  # no node near a tie
    assert s["min/info"][2] == p["min/info"][2]
    assert np.allclose(s["min/X"], p["min/X"], atol=1e-12)
    assert np.max(np.abs(s["min/u"] - p["min/u"])) <= 1e-8
    assert np.max(np.abs(s["min/lambda"] - p["min/lambda"])) <= 1e-8 * np.max(
        np.abs(s["min/lambda"])
    )
    assert s["min/info"][4] < 1e-10 and p["min/info"][4] < 1e-10  # action = reaction


@pytest.fixture(scope="module")
def patch_3d():
    scene = contact.load_scene(PATCH_3D, P2)
    return scene, build_problem(scene)


def test_p2_patch_3d_pressure_is_exact_at_every_slave_node(patch_3d):
    """13 × 13 against 4 × 4 interface cells, P2 tetrahedra: the slave nodes' unknowns are
    the transformed values (every basis function of a P2 triangle integrating positively),
    λ_i = −p at all 27² slave nodes (vertices and edges) and λ^m_j = −p at all 9² master
    nodes to 1e-8, forces balanced, the contact force p × area."""
    scene, problem = patch_3d
    r = contact.solve(scene, method="min", problem=problem, verbose=False)
    assert r.converged
    lam = r.lmbda_h.x.array[problem.output.nodes]
    assert len(lam) == 27 * 27 == r.n_active
    assert np.max(np.abs(lam + P)) <= 1e-8 * P
    lam_m = master_pressure(r).x.array
    master = np.abs(lam_m) > 0
    assert master.sum() == 9 * 9 and np.max(np.abs(lam_m[master] + P)) <= 1e-8 * P
    res = resultants(posed_of(scene), r)
    assert res["interface_balance_error"] < 1e-10
    assert res["contact_force"] == pytest.approx(4 * P, rel=1e-10)  # mirrored at x = 0, y = 0


@pytest.mark.mpi
def test_p2_patch_3d_on_two_ranks_equals_serial(tmp_path):
    args = ["--methods=min", "--set=mesh.degree=2"]
    s, p = run(tmp_path, PATCH_3D, 1, *args), run(tmp_path, PATCH_3D, 2, *args)
    for res in (s, p):
        assert res["min/info"][0] == 1 and len(res["min/lambda"]) == 27 * 27
        assert np.max(np.abs(res["min/lambda"] + P)) <= 1e-8 * P
        assert np.max(np.abs(res["min/lambda_master"] + P)) <= 1e-8 * P
        assert res["min/info"][4] < 1e-10  # action = reaction
    assert np.allclose(s["min/Xs"], p["min/Xs"], atol=1e-14)
    assert np.max(np.abs(s["min/u"] - p["min/u"])) <= 1e-8 * np.max(np.abs(s["min/u"]))


#: the 3D finite-strain patch at P2 on coarse non-matching blocks (3 × 3 slave triangles' squares
#: on 2 × 2 master ones) and at the nominal pressure 0.15: at 0.2, the 2D and P1 tests' load, the
#: P2 tangent on the free unknowns has a negative eigenvalue at the homogeneous solution (the
#: column with its frictionless slip plane is unstable there), the energy line search follows
#: the direction of negative curvature off it and the load path returns to it after tens of
#: Newton steps
FINITE_P_3D = 0.15
FINITE_PATCH_3D_P2 = [
    *PATCH_3D_FINITE,
    f"constants.p={FINITE_P_3D}",
    "mesh.degree=2",
    "mesh.blocks=[{corners: [[0, 0, 0], [1, 1, 0.5]], cells: [2, 2, 2]},"
    " {corners: [[0, 0, 0.5], [1, 1, 1]], cells: [3, 3, 3]}]",
]


def test_p2_finite_strain_patch_3d_is_the_exact_cauchy_traction():
    """The neo-Hookean 3D patch at P2 (non-matching, re-coupled on the current
    configuration, the slave triangles' transformed basis): every one of the 7² slave
    nodes carries P/λ₁² to 1e-8 (8 % off nominal), u = (λ − 1) X at every node, the slave
    and master surface forces cancel, and the solution is a stable equilibrium."""
    scene = contact.load_scene(PATCH_3D, ["output.verbose=false", *FINITE_PATCH_3D_P2])
    run_ = contact.run_load_path(scene, verbose=False)
    assert run_.converged
    r = run_.steps[-1].result
    assert r.couplings[-1]["change"] <= 1e-12
    l1, l2 = uniaxial(3, FINITE_P_3D)
    p = r.problem
    pressure = p.pressure(owned_residual(r))[: p.data.pair_nodes]
    assert len(pressure) == 7 * 7
    exact = FINITE_P_3D / l1**2
    assert np.max(np.abs(pressure / exact - 1)) <= 1e-8 and abs(exact / FINITE_P_3D - 1) > 0.05
    X = p.V.tabulate_dof_coordinates()
    u = r.u_h.x.array.reshape(-1, 3)
    assert np.max(np.abs(u - X * np.r_[l1 - 1, l1 - 1, l2 - 1])) <= 1e-8 * (1 - l2)
    slave, master = interface_force(r, scene, "slave"), interface_force(r, scene, "master")
    assert abs(slave[-1] - FINITE_P_3D) <= 1e-10 * FINITE_P_3D
    assert abs(slave[-1] + master[-1]) <= 1e-12 * FINITE_P_3D
    assert negative_eigenvalues(r) == 0


@pytest.mark.mpi
def test_p2_finite_strain_patch_3d_on_two_ranks_equals_serial(tmp_path):
    s = run_finite(tmp_path, PATCH_3D, 1, *FINITE_PATCH_3D_P2)
    p = run_finite(tmp_path, PATCH_3D, 2, *FINITE_PATCH_3D_P2)
    l1, _ = uniaxial(3, FINITE_P_3D)
    for res in (s, p):
        assert res["converged"] and len(res["pressure"]) == 7 * 7
        assert np.max(np.abs(res["pressure"] * l1**2 / FINITE_P_3D - 1)) <= 1e-8
    assert np.allclose(s["X"], p["X"], atol=1e-14)
    assert abs(s["force"] - p["force"]) <= 1e-12 * abs(s["force"])


#: the frictional 3D patch (configs/two_body_friction_patch_3d.yaml): pressure, Coulomb F,
#: the top's drag and the blocks' shear compliance Σ h/G (ν = 0, G = E/2)
FRICTION_P, FRICTION_F, DRAG, COMPLIANCE = 0.015, 0.3, 0.02, 0.5 / 1.5 + 0.5 / 0.5
#: case -> (overrides, |λ_t| at every slave node, slip increment along x)
FRICTION_CASES = {
    "coulomb slides": ([], FRICTION_F * FRICTION_P, DRAG - FRICTION_F * FRICTION_P * COMPLIANCE),
    "tresca slides": (
        [
            "friction={law: tresca, threshold: 0.004}",
            "constants.tau=0.004",
        ],
        0.004,
        DRAG - 0.004 * COMPLIANCE,
    ),
    "coulomb sticks": (["constants.drag=0.003", "constants.tau=0.00225"], 0.003 / COMPLIANCE, 0),
}


def exact_friction_patch(V, drag: float, tau: float) -> np.ndarray:
    """The friction patch's displacement at the nodes of V: simple shear tau / G and
    compression p / E in each block (lower: E = 1, clamped at z = 0; upper: E = 3, its top
    moved by (drag, 0, −δ)); a node's block is that of its cells (the interface nodes of
    both blocks share their coordinates)."""
    X = V.tabulate_dof_coordinates()
    cells = V.dofmap.list
    lower = np.zeros(len(X), dtype=bool)
    lower[cells[X[cells, 2].mean(axis=1) < 0.5].ravel()] = True
    z = X[:, 2]
    ux = np.where(lower, tau * z / 0.5, drag - tau * (1 - z) / 1.5)
    uz = np.where(lower, -FRICTION_P * z, -0.01 + FRICTION_P * (1 - z) / 3)
    return np.c_[ux, np.zeros_like(z), uz]


@pytest.fixture(scope="module")
def friction_patches():
    """The frictional 3D patch at P1 and P2, each case solved once."""
    out = {}
    for degree in (1, 2):
        for case, (sets, _, _) in FRICTION_CASES.items():
            scene = contact.load_scene(
                FRICTION_PATCH_3D, ["output.verbose=false", f"mesh.degree={degree}", *sets]
            )
            path = contact.run_load_path(scene, verbose=False)
            assert path.converged
            out[degree, case] = scene, path.steps[-1].result
    return out


@pytest.mark.parametrize("case", sorted(FRICTION_CASES))
@pytest.mark.parametrize("degree", [1, 2])
def test_friction_patch_3d_is_exact_at_every_slave_node(friction_patches, degree, case):
    """Two non-matching blocks (7 × 7 against 4 × 4 interface cells) pressed and sheared:
    at every slave node (P2: vertices and edge nodes, the transformed basis) λ_n = −p and the
    tangential traction is (−τ, 0, 0) with τ = F p (Coulomb, sliding), the threshold
    (Tresca, sliding) or the elastic shear (sticking, below F p) to 1e-10 relative; the slip
    increment is the drag less the blocks' shear (sliding) or zero (sticking); every node
    of both bodies has the exact displacement, so P1 and P2 give the same solution."""
    scene, r = friction_patches[degree, case]
    _, traction, slip = FRICTION_CASES[case]
    p, fr = r.problem, r.friction
    on = slice(0, p.data.pair_nodes)
    assert p.data.pair_nodes == {1: 8 * 8, 2: 15 * 15}[degree]
    assert np.all(fr["status"][on] == (SLIP if slip else STICK))
    assert np.max(np.abs(fr["lambda_n"][on] / FRICTION_P + 1)) <= 1e-10
    expected = np.array([-traction, 0, 0])
    assert np.max(np.abs(fr["lambda_t_vec"][on] - expected)) <= 1e-10 * traction
    assert np.max(np.abs(np.linalg.norm(fr["lambda_t"][on], axis=1) / traction - 1)) <= 1e-10
    assert np.max(np.abs(fr["slip_vec"][on] - [slip, 0, 0])) <= 1e-10 * DRAG
    drag = 0.003 if "sticks" in case else DRAG
    u = r.u_h.x.array.reshape(-1, 3)
    assert np.max(np.abs(u - exact_friction_patch(p.V, drag, traction))) <= 1e-10 * DRAG
    assert resultants(posed_of(scene), r)["interface_balance_error"] < 1e-10


#: the frictional 3D patch on 4 × 4 against 3 × 3 interface cells, one cell thick
COARSE_BLOCKS = (
    "mesh.blocks=[{corners: [[0, 0, 0], [1, 1, 0.5]], cells: [3, 3, 1]},"
    " {corners: [[0, 0, 0.5], [1, 1, 1]], cells: [4, 4, 1]}]"
)


def test_p2_friction_patch_3d_slides_at_finite_strain():
    """The frictional 3D patch with neo-Hookean blocks (4 × 4 against 3 × 3 interface cells,
    P2, re-coupled on the current configuration): dragged, every slave node still facing
    the master slides on the Coulomb bound |λ_t| = F |λ_n| to 1e-10, and the slave and
    master surface forces cancel; the slave's tangential force is F × its normal force to
    1 % (measured 0.2 %: the nodes slid past the master's edge carry nothing)."""
    scene = contact.load_scene(FRICTION_PATCH_3D, [*P2, *HYPERELASTIC, COARSE_BLOCKS])
    path = contact.run_load_path(scene, verbose=False)
    assert path.converged
    r = path.steps[-1].result
    p, fr = r.problem, r.friction
    on = slice(0, p.data.pair_nodes)
    assert p.data.pair_nodes >= 9 * 9 - 9  # the slave's far edge has slid past the master's
    assert np.all(fr["status"][on] == SLIP)
    bound = FRICTION_F * np.abs(fr["lambda_n"][on])
    assert np.max(np.abs(np.linalg.norm(fr["lambda_t"][on], axis=1) / bound - 1)) <= 1e-10
    slave, master = interface_force(r, scene, "slave"), interface_force(r, scene, "master")
    assert np.max(np.abs(slave + master)) <= 1e-10 * np.max(np.abs(slave))
    # the friction force against the drag: F × the normal force but for the uncovered edge
    assert slave[2] > 0 and -slave[0] == pytest.approx(FRICTION_F * slave[2], rel=0.01)


def friction_table(folder) -> np.ndarray:
    """contact.csv of a run (a structured array, rows sorted by coordinates)."""
    table = np.genfromtxt(
        folder / "contact.csv", delimiter=",", names=True, dtype=None, encoding=None
    )
    return table[np.lexsort([np.round(table[c], 10) for c in "zyx"])]


@pytest.mark.mpi
def test_p2_friction_patch_3d_cli_on_two_ranks_equals_serial(tmp_path):
    """``contact run configs/two_body_friction_patch_3d.yaml --set mesh.degree=2`` serially
    and on 2 ranks, every output file read back: the contact tables have λ_n = −p,
    λ_t = (−F p, 0, 0), the bound F p and the slip of the exact solution at all 225 slave
    nodes, all slipping, to 1e-10, and the two runs' tables agree to 1e-10."""
    tables = []
    for ranks in (0, 2):
        out, _ = run_scene(tmp_path, FRICTION_PATCH_3D.name, ranks, ["mesh.degree=2"], 300)
        read_folder(out)
        t = friction_table(out)
        tau, slip = FRICTION_F * FRICTION_P, DRAG - FRICTION_F * FRICTION_P * COMPLIANCE
        assert len(t) == 15 * 15 and set(t["status"]) == {"slip"}
        assert np.max(np.abs(t["lambda_n"] + FRICTION_P)) <= 1e-10 * FRICTION_P
        for name, value in (("lambda_t_x", -tau), ("lambda_t_norm", tau), ("bound", tau)):
            assert np.max(np.abs(t[name] - value)) <= 1e-10 * tau, name
        assert np.max(np.abs(t["lambda_t_y"])) <= 1e-10 * tau
        assert np.max(np.abs(t["slip_x"] - slip)) <= 1e-10 * DRAG
        tables.append(t)
    for name in tables[0].dtype.names:
        if name != "status":
            assert np.allclose(tables[0][name], tables[1][name], rtol=0, atol=1e-10), name


@pytest.mark.mpi
def test_p2_friction_patch_3d_at_finite_strain_on_two_ranks_equals_serial(tmp_path):
    """The neo-Hookean frictional P2 patch (coarse blocks) through the command line, serially
    and on 2 ranks: the same slave nodes, all slipping, the contact tables' columns equal to
    1e-10 of their unit's scale — lengths (coordinates, gap, slip) of the blocks' size 1,
    tractions of the largest |λ_n| — (measured 2.4e-14 for λ_n)."""
    sets = ["mesh.degree=2", *HYPERELASTIC, COARSE_BLOCKS, "output.png=false"]
    s, p = (
        friction_table(run_scene(tmp_path, FRICTION_PATCH_3D.name, n, sets, 300)[0]) for n in (0, 2)
    )
    assert len(s) == len(p) >= 9 * 9 - 9
    assert set(s["status"]) == set(p["status"]) == {"slip"}
    traction = np.max(np.abs(s["lambda_n"]))
    for name in s.dtype.names:
        if name != "status":
            length = name in ("x", "y", "z", "r", "gap") or name.startswith("slip")
            pulls = name.startswith("lambda") or name == "bound"
            scale = 1.0 if length else traction if pulls else np.max(np.abs(s[name]))
            assert np.max(np.abs(s[name] - p[name])) <= 1e-10 * scale, name


def nodal_deviation(scene, r) -> tuple[float, float]:
    """(max over the slave nodes within 0.8 a of |p_i − p_Hertz(x_i)|, p_max − p0), both
    over Hertz's p0 for the computed force.  Serial."""
    p = r.problem
    X = p.output.space.tabulate_dof_coordinates()[p.output.nodes, 0]
    pressure = -r.lmbda_h.x.array[p.output.nodes]
    ref = compare(posed_of(scene), r).values
    a, p0 = ref["hertz_a"], ref["hertz_p0"]
    inner = np.abs(X) < 0.8 * a
    hertz = p0 * np.sqrt(1 - (X[inner] / a) ** 2)
    return np.max(np.abs(pressure[inner] - hertz)) / p0, np.max(pressure) / p0 - 1


def test_p2_cylinders_with_the_arcs_gap_meet_hertz_at_every_node():
    """Where the P2 nodal pressures' alternation comes from: the gaps of the straight
    facets.  Given the gap of the two circles themselves at every slave node, g(x) = 2 R_c
    − 2 √(R_c² − x²) (the midpoints' gaps move by the facets' sagittas, ~1e-4), the same
    coupling gives every nodal pressure within 1 % of Hertz's over |x| < 0.8 a (measured
    0.45 %; P1 on the same mesh, whose vertices lie on the arcs, 1.8 %; P2 with the facets'
    gaps 9.6 %) and the peak within 1 % of p0 (measured −0.36 %)."""
    deviation = {}
    for degree, arcs in ((1, False), (2, False), (2, True)):
        scene = contact.load_scene(HERTZ_2D, [*COARSE_2D, f"mesh.degree={degree}"])
        problem = build_problem(scene)
        c, bs = problem.constraint, problem.V.dofmap.index_map_bs
        if arcs:
            x = problem.V.tabulate_dof_coordinates()[c.dofs // bs, 0]
            exact = 16.0 - 2.0 * np.sqrt(64.0 - x**2)  # R_c = 8, touching at x = 0
            assert 1e-5 < np.max(np.abs(c.g - exact)[np.abs(x) < 0.5]) < 1e-3  # sagittas
            c.g[:] = exact
        r = contact.solve(scene, method="min", problem=problem, verbose=False)
        assert r.converged
        deviation[degree, arcs] = nodal_deviation(scene, r)
    assert deviation[2, True][0] < 0.01 and abs(deviation[2, True][1]) < 0.01
    assert deviation[2, True][0] < 0.5 * deviation[1, False][0] < deviation[2, False][0]
