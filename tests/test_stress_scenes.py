"""The stress-test scenes of the solver stability study (serial, small meshes).

* ``configs/obtuse_square.yaml``: ``mesh.map`` shears the right-diagonal unit square,
  x' = x + s y.  At s = 1 every triangle has a 135° angle and the P1 stiffness K has
  positive off-diagonal entries (it is no longer an M-matrix); at s = 0 it has none.
  (fb / min / blend against vinewtonrsls on it, serial and on 2 ranks: test_agreement.py.)
* ``configs/biactive.yaml``: u = y² touches the obstacle g = 0 on y = 0 with zero flux, so
  at the discrete solution every contact node is biactive: g_i − u_i = 0 and λ_i = 0;
  fb and min reach vinewtonrsls' solution to 1e-8.  (Not in test_agreement.py: it compares
  active-set sizes, and with every pair (a_i, b_i) = (0, 0) up to round-off the rule
  b_i > a_i classifies the nodes by round-off.)
"""

from __future__ import annotations

from pathlib import Path

import contact
from contact.adaptivity.energy_error import energy_error
from contact.setup.build import build_problem
from contact.solvers import owned_residual

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
OBTUSE = ROOT / "configs" / "obtuse_square.yaml"
BIACTIVE = ROOT / "configs" / "biactive.yaml"
N = 8  # cells per side of the obtuse tests


def _largest_angles(msh) -> np.ndarray:
    """The largest interior angle of each triangle, in degrees."""
    P = msh.geometry.x[msh.geometry.dofmaps[0]][:, :, :2]
    angles = []
    for k in range(3):
        a, b = P[:, (k + 1) % 3] - P[:, k], P[:, (k + 2) % 3] - P[:, k]
        cos = np.sum(a * b, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        angles.append(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    return np.max(angles, axis=0)


def _off_diagonal(K) -> tuple[np.ndarray, float]:
    """The off-diagonal entries of K's owned rows, and max |K_ii| (the round-off scale)."""
    indptr, cols, vals = K.getValuesCSR()
    rows = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr)) + K.getOwnershipRange()[0]
    return vals[rows != cols], float(np.max(np.abs(vals[rows == cols])))


@pytest.mark.parametrize("shear, angle, positive", [(0.0, 90.0, 0), (1.0, 135.0, 2 * N * (N - 1))])
def test_sheared_stiffness_has_positive_off_diagonal_entries(shear, angle, positive):
    """K_ij = −(cot α + cot β)/2 for an edge with opposite angles α, β (k = 1).  Sheared,
    both angles opposite a square's diagonal are 135°: K_ij = +1 on every diagonal that does
    not touch the Dirichlet top (whose rows and columns are identity), i.e. on 2 N (N − 1)
    entries; unsheared they are 90°: K_ij = 0 up to round-off, and K is an M-matrix."""
    scene = contact.load_scene(OBTUSE, [f"constants.s={shear}", f"mesh.cells=[{N},{N}]"])
    assert np.allclose(_largest_angles(scene.mesh), angle)
    off, scale = _off_diagonal(build_problem(scene).K)
    is_positive = off > 1e-12 * scale
    assert np.count_nonzero(is_positive) == positive
    assert np.allclose(off[is_positive], 1.0)


def _contact_state(result: contact.Result) -> tuple[np.ndarray, np.ndarray]:
    """Gap g_i − u_i [length] and multiplier λ_i = R_i / w_i [flux] on the contact nodes."""
    con = result.problem.constraint
    return con.g - result.u_h.x.array[con.dofs], owned_residual(result)[con.dofs] / con.w


@pytest.fixture(scope="module")
def biactive() -> dict[str, contact.Result]:
    """The biactive scene at 16 × 16 solved from u = 0 by fb, min and vinewtonrsls (a
    problem, and so a u_h, of its own for each)."""
    scene = contact.load_scene(BIACTIVE, ["mesh.cells=[16,16]"])
    return {m: contact.solve(scene, method=m, verbose=False) for m in ("fb", "min", "vinewtonrsls")}


@pytest.mark.parametrize("method", ["fb", "min"])
def test_biactive_methods_agree_with_vinewtonrsls(biactive, method):
    ours, ref = biactive[method], biactive["vinewtonrsls"]
    assert ours.converged and ref.converged
    diff = np.max(np.abs(ours.u_h.x.array - ref.u_h.x.array))
    assert diff <= 1e-8, f"max nodal difference {diff:.1e}"


@pytest.mark.parametrize("method", ["fb", "min", "vinewtonrsls"])
def test_every_contact_node_is_biactive(biactive, method):
    """|g_i − u_i| / U ≤ 1e-8 and |λ_i| / (k U / L) ≤ 1e-8 with U = max |u_h| (= u_D = 1)
    and L = 1 the side of the square: on all contact nodes (at least 90% required)."""
    result = biactive[method]
    gap, lam = _contact_state(result)
    U, L = np.max(np.abs(result.u_h.x.array)), 1.0
    both = (np.abs(gap) / U <= 1e-8) & (np.abs(lam) / (U / L) <= 1e-8)
    assert len(gap) == 17 and np.mean(both) >= 0.9, (
        f"max |g - u| {np.abs(gap).max():.1e}, max |λ| {np.abs(lam).max():.1e}"
    )


def test_biactive_energy_error_is_first_order():
    """‖∇(y² − u_h)‖ ≤ h/2 and halves with h (P1, O(h)); and the obstacle changes nothing:
    with it moved away (g = 1) the discrete solution is the same to round-off."""
    errors = []
    for n in (16, 32):
        scene = contact.load_scene(BIACTIVE, [f"mesh.cells=[{n},{n}]"])
        u_h = contact.solve(scene, verbose=False).u_h
        errors.append(energy_error(u_h, "y**2"))
        assert errors[-1] <= 0.5 / n
    free = contact.solve(
        contact.load_scene(BIACTIVE, ["mesh.cells=[32,32]", "data.g=1"]), verbose=False
    )
    assert free.n_active == 0  # the obstacle 1 away: every node far from the tie
    assert np.max(np.abs(free.u_h.x.array - u_h.x.array)) <= 1e-10
    assert 1.9 <= errors[0] / errors[1] <= 2.1
