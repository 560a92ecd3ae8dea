"""The baseline enforcements (contact.solvers.baselines, docs/theory.md §10): penalty,
augmented Lagrangian (Uzawa) and Nitsche converge with their default parameters on problem A,
Hertz 2D and Hertz 3D and agree with Fischer–Burmeister to O(their parameter); the penalty's
error is O(1/ε₀), Nitsche's optimal in h; symmetric Nitsche loses coercivity for a small γ₀
where the skew-symmetric variant does not; serial = 2 ranks; scenes run them through the CLI;
bad input is one line.  Small meshes: the sweeps are demos/bench/bench_baselines.py."""

from __future__ import annotations

import json

import contact
from contact import ConfigError
from contact.adaptivity.energy_error import energy_error
from contact.solvers.baselines import penetration

import numpy as np
import pytest
from clirun import ROOT, script_json
from clirun import contact as contact_cli

A = str(ROOT / "configs" / "signorini_free_boundary.yaml")
HERTZ_2D = str(ROOT / "configs" / "hertz_2d.yaml")
HERTZ_3D = str(ROOT / "configs" / "hertz_3d.yaml")
TWO_BODIES = str(ROOT / "configs" / "two_body_hertz_2d.yaml")
COARSE_BODIES = ["mesh.h=2.0", "mesh.h_contact=0.1", "mesh.zone=1.0"]
SCENES = {
    "A": (A, ["adapt=null", "mesh.cells=[32,16]"]),
    "hertz_2d": (HERTZ_2D, ["adapt=null", "mesh.h_contact=0.01"]),
    "hertz_3d": (HERTZ_3D, ["adapt=null", "mesh.h_contact=0.04"]),
}
#: (method, options) with the defaults: ε₀ = 1e3, r₀ = 100, γ₀ = 10
VARIANTS = {
    "penalty": ("penalty", {}),
    "augmented_lagrangian": ("augmented_lagrangian", {}),
    "nitsche": ("nitsche", {}),
    "nitsche_skew": ("nitsche", {"nitsche_theta": -1}),
}
#: |F / F_fb − 1| with the default parameter, at most (measured: penalty 1.9e-4 on A at
#: ε₀ = 1e3, 4.7e-5 / 2.6e-4 on the Hertz scenes; the augmented Lagrangian to its Uzawa
#: tolerance; Nitsche a discretization difference, 1e-5 … 4e-3)
FORCE_TOLERANCE = {
    "penalty": 1e-3,
    "augmented_lagrangian": 1e-7,
    "nitsche": 1e-2,
    "nitsche_skew": 1e-2,
}


@pytest.fixture(scope="module")
def fb_runs() -> dict:
    """fb on each scene: (scene, result)."""
    out = {}
    for name, (path, sets) in SCENES.items():
        scene = contact.load_scene(path, sets)
        out[name] = scene, contact.solve(scene, method="fb", verbose=False)
    return out


@pytest.mark.parametrize("variant", list(VARIANTS))
@pytest.mark.parametrize("name", list(SCENES))
def test_converges_with_defaults_and_agrees_with_fb(fb_runs, name: str, variant: str) -> None:
    scene, fb = fb_runs[name]
    method, options = VARIANTS[variant]
    r = contact.solve(scene, method=method, verbose=False, **options)
    assert r.converged, (r.reason, r.iterations)
    assert r.method == method
    rel = abs(r.contact_force / fb.contact_force - 1.0)
    assert rel <= FORCE_TOLERANCE[variant], rel
    assert r.n_active > 0
    depth = penetration(r)
    scale = float(np.max(np.abs(fb.u_h.x.array)))
    if method == "augmented_lagrangian":  # Uzawa's fixed point is the exact constraint
        assert depth <= 1e-8 * scale
        assert r.outer_iterations >= 2
    elif method == "penalty":  # O(1/ε₀) of the displacement scale
        assert 0 < depth <= 1e-2 * scale
    # λ_h is the method's own nodal pressure: ≤ 0 (compression) on every contact node
    assert float(np.max(r.problem.multiplier(r.contact_residual), initial=0.0)) <= 0.0


@pytest.mark.parametrize("path, sets", [(A, ["mesh.cells=[16,8]"]), (TWO_BODIES, COARSE_BODIES)])
def test_penalty_converges_to_fb_like_one_over_epsilon(path: str, sets: list[str]) -> None:
    """‖u_ε − u_fb‖ and the penetration fall 10× per decade of ε₀ (observed order −1.00 on
    problem A and on two bodies through the mortar gap; bench_baselines.py: −0.99 to −1.00
    on all four problems)."""
    scene = contact.load_scene(path, ["adapt=null", "output.verbose=false", *sets])
    fb = contact.solve(scene, method="fb", verbose=False)
    dist, depth = [], []
    for eps in (1e2, 1e3, 1e4):
        r = contact.solve(scene, method="penalty", epsilon0=eps, verbose=False)
        assert r.converged
        dist.append(float(np.linalg.norm(r.u_h.x.array - fb.u_h.x.array)))
        depth.append(penetration(r))
    for series in (dist, depth):
        ratios = [series[k] / series[k + 1] for k in range(2)]
        assert all(9.0 < q < 11.0 for q in ratios), ratios


def test_augmented_lagrangian_reaches_fb_for_every_r() -> None:
    """Uzawa's fixed point is the discrete complementarity solution whatever r: fb's
    solution to the outer tolerance, in more outer iterations for a smaller r."""
    scene = contact.load_scene(A, ["adapt=null", "mesh.cells=[16,8]"])
    fb = contact.solve(scene, method="fb", verbose=False)
    outer = []
    for r0 in (1.0, 100.0, 1e4):
        r = contact.solve(scene, method="augmented_lagrangian", r0=r0, verbose=False)
        assert r.converged
        assert np.max(np.abs(r.u_h.x.array - fb.u_h.x.array)) < 1e-7
        outer.append(r.outer_iterations)
    assert outer[0] > outer[1] >= outer[2]


def test_nitsche_optimal_in_h_on_the_smooth_problem() -> None:
    """Problem C (smooth, u ∈ H³): Nitsche's energy error falls like h, as fb's (P1 optimal;
    measured rates 1.00 and 1.00 on 8² … 32²), and both errors agree to 10 %."""
    errors: dict[str, list[float]] = {"fb": [], "nitsche": [], "nitsche_skew": []}
    path = str(ROOT / "configs" / "signorini_smooth.yaml")
    for n in (8, 16, 32):
        scene = contact.load_scene(path, ["adapt=null", f"mesh.cells=[{n},{n}]"])
        exact = scene.config.data.exact
        assert isinstance(exact, str)
        for key in errors:
            method, options = ("fb", {}) if key == "fb" else VARIANTS[key]
            r = contact.solve(scene, method=method, verbose=False, **options)
            assert r.converged
            errors[key].append(energy_error(r.u_h, exact))
    for key, e in errors.items():
        rates = [np.log2(e[k] / e[k + 1]) for k in range(2)]
        assert min(rates) > 0.9, (key, rates)
        assert abs(e[-1] / errors["fb"][-1] - 1.0) < 0.1, key


def test_symmetric_nitsche_loses_coercivity_for_small_gamma() -> None:
    """θ = 1 with γ₀ = 1e-3: the symmetric term −(1/γ) σ_n(u) σ_n(v) outweighs a(u, v) and
    Newton does not converge; θ = −1 is coercive for every γ₀ and converges."""
    scene = contact.load_scene(A, ["adapt=null", "mesh.cells=[16,8]", "solver.max_it=30"])
    sym = contact.solve(scene, method="nitsche", gamma0=1e-3, verbose=False)
    skew = contact.solve(scene, method="nitsche", gamma0=1e-3, nitsche_theta=-1, verbose=False)
    assert not sym.converged
    assert skew.converged


@pytest.mark.parametrize(
    "method, options",
    [("penalty", {}), ("nitsche", {}), ("augmented_lagrangian", {})],
    ids=["penalty", "nitsche", "augmented_lagrangian"],
)
def test_friction_agrees_with_min(method: str, options: dict) -> None:
    """Coulomb friction, one load step of the block pressed and dragged (stick and slip
    zones): normal and tangential forces within 1 % of min's; the same stick/slip split up to
    a node or two."""
    scene = contact.load_scene(
        str(ROOT / "configs" / "friction_block_2d.yaml"),
        ["mesh.cells=[40,10]", "load=null", 'data.u_D=["0.002", "-0.01"]'],
    )
    ref = contact.solve(scene, method="min", verbose=False)
    r = contact.solve(scene, method=method, verbose=False, **options)
    assert r.converged, r.reason
    assert r.friction is not None and ref.friction is not None
    w = ref.friction["w"]
    for key in ("lambda_n", "lambda_t"):
        total = float(np.sum(w * np.ravel(r.friction[key])))
        expected = float(np.sum(w * np.ravel(ref.friction[key])))
        assert abs(total / expected - 1.0) < 1e-2, (key, total, expected)
    for code in (1, 2):  # stick, slip
        count = int(np.sum(r.friction["status"] == code))
        assert abs(count - int(np.sum(ref.friction["status"] == code))) <= 2


PARALLEL = """
import json, sys
from mpi4py import MPI
import contact
from contact.solvers.baselines import penetration
out = {}
for path, sets in json.loads(sys.argv[1]):
    scene = contact.load_scene(path, sets)
    for method, options in json.loads(sys.argv[2]):
        r = contact.solve(scene, method=method, verbose=False, **options)
        key = path.rsplit("/", 1)[-1] + " " + method + json.dumps(options)
        out[key] = [r.converged, r.n_active, r.contact_force, penetration(r)]
if MPI.COMM_WORLD.rank == 0:
    print(json.dumps(out))
"""


def test_serial_equals_two_ranks(tmp_path) -> None:
    """Each method on problem A (2D, MUMPS) and on hertz_3d (3D, CG / GMRES + GAMG): the same
    active set, contact force and penetration on 1 and 2 ranks (to solver tolerance)."""
    scenes = [SCENES["A"], SCENES["hertz_3d"]]
    methods = list(VARIANTS.values())
    one = {}  # serial: in this process
    for path, sets in scenes:
        scene = contact.load_scene(path, sets)
        for method, options in methods:
            r = contact.solve(scene, method=method, verbose=False, **options)
            key = path.rsplit("/", 1)[-1] + " " + method + json.dumps(options)
            one[key] = [r.converged, r.n_active, r.contact_force, penetration(r)]
    two = script_json(PARALLEL, tmp_path, json.dumps(scenes), json.dumps(methods), ranks=2)
    assert isinstance(two, dict)
    assert one.keys() == two.keys() and len(one) == 8
    for key, (conv, active, force, depth) in one.items():
        conv2, active2, force2, depth2 = two[key]
        assert conv and conv2, key
        assert active == active2, key
        assert force2 == pytest.approx(force, rel=1e-8), key
        assert depth2 == pytest.approx(depth, rel=1e-6, abs=1e-14), key


def test_cli_run_writes_the_parameter_and_the_penetration(tmp_path) -> None:
    """``contact run … --set solver.method=nitsche``: exit 0, summary.json names the method,
    γ₀, θ and the largest penetration, and compares with Hertz."""
    proc = contact_cli(
        tmp_path,
        "run",
        HERTZ_2D,
        "-o",
        "out",
        "-q",
        "--set",
        "adapt=null",
        "--set",
        "mesh.h_contact=0.01",
        "--set",
        "solver.method=nitsche",
        "--set",
        "solver.nitsche_theta=-1",
        "--set",
        "output.png=false",
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["method"] == "nitsche" and summary["converged"]
    assert summary["gamma0"] == 10.0 and summary["nitsche_theta"] == -1.0
    assert 0.0 < summary["penetration"] < 1e-3
    assert abs(summary["p0_error"]) < 0.05


@pytest.mark.parametrize(
    "scene, sets, message",
    [
        (
            "obstacle_membrane.yaml",
            ["solver.method=nitsche"],
            "solver.method: nitsche needs a contact boundary",
        ),
        (
            "signorini_smooth.yaml",
            ["solver.method=penalty", "mesh.degree=2"],
            "mesh.degree: penalty integrates its contact term at the vertices",
        ),
        (
            "two_body_patch_2d.yaml",
            ["solver.method=nitsche"],
            "solver.method: nitsche takes one body against a rigid obstacle",
        ),
        (
            "hyperelastic_block.yaml",
            ["solver.method=augmented_lagrangian"],
            "solver.method: augmented_lagrangian is available for scalar scenes",
        ),
        (
            "signorini_square.yaml",
            ["solver.method=nitsche", "solver.nitsche_theta=2"],
            "solver.nitsche_theta: must be 1, 0 or -1, got 2.0",
        ),
        (
            "signorini_square.yaml",
            ["solver.method=penalty", "solver.epsilon0=-1"],
            "solver.epsilon0: must be > 0",
        ),
    ],
)
def test_bad_input_is_one_line(scene: str, sets: list[str], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        contact.load_scene(str(ROOT / "configs" / scene), sets)
    assert str(err.value).startswith(message), str(err.value)
    assert "\n" not in str(err.value)
