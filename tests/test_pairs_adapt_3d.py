"""The adaptive loop with two bodies in contact in 3D: the sphere on a block
(configs/two_body_hertz_3d.yaml on a coarse mesh), coupled by dual-mortar pairs, refined by
Dörfler marking of the residual estimator with its interface terms.

At small strain Dörfler's force is closer to the finest uniform level's than uniform
refinement's at as many DoFs.  At finite strain (neo-Hookean) each level solves its own fixed
point of couplings on the current configuration and the interface terms compare P(u_h)N with
the pressures per current area along the current normals (as in 2D,
tests/test_hyperelastic_pairs_adapt.py): at a small load η and the meshes are the linear
elastic ones; at δ = 0.05 R the force converges with the levels and the interface forces
balance.  The CLI gives the same meshes, η and forces serially and on 2 ranks."""

from __future__ import annotations

import csv
import json
import warnings

import contact
from contact.base.errors import ContactWarning
from contact.post.interface import resultants

import numpy as np
import pytest
from clirun import ROOT
from clirun import contact as cli

SPHERE = ROOT / "configs" / "two_body_hertz_3d.yaml"
COARSE = ["mesh.h=0.5", "mesh.h_contact=0.1"]
NEO_HOOKEAN = ["model.type=hyperelastic", "model.law=neo_hookean"]


def levels(*sets: str, max_levels: int = 3) -> list[dict]:
    """DoFs, η, the contact force, the interface balance and convergence of each level of
    the adaptive loop on the coarse sphere on a block with ``sets``."""
    scene = contact.load_scene(SPHERE, ["output.verbose=false", *COARSE, *sets])
    rows: list[dict] = []

    def record(level) -> None:
        r = level.result
        balance = resultants(level.posed, r)["interface_balance_error"]
        rows.append(
            {
                "dofs": r.dofs,
                "eta": level.estimate.eta,
                "force": r.contact_force,
                "balance": balance,
                "converged": bool(r.converged),
            }
        )

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "boundary: .* exterior facet", ContactWarning)
        contact.adapt(scene, max_levels=max_levels, verbose=False, on_level=record)
    assert len(rows) == max_levels and all(row["converged"] for row in rows)
    return rows


def column(rows: list[dict], key: str) -> np.ndarray:
    return np.array([row[key] for row in rows])


def test_dorfler_is_closer_to_the_fine_uniform_force_with_fewer_dofs():
    """Small strain, 3 levels each: η falls under both; Dörfler's last level has fewer DoFs
    than uniform's second (3,600 against 3,762) and its force is closer to uniform's third
    (24,234 DoFs) by a factor < 0.75 (measured 0.58); the interface forces balance
    to 1e-8."""
    dorfler, uniform = levels(), levels("adapt.strategy=uniform")
    for rows in (dorfler, uniform):
        eta = column(rows, "eta")
        assert np.all(np.diff(eta) < 0)
        assert np.all(column(rows, "balance") < 1e-8)
    fine = uniform[-1]["force"]
    assert dorfler[-1]["dofs"] < uniform[1]["dofs"]
    assert abs(dorfler[-1]["force"] - fine) < 0.75 * abs(uniform[1]["force"] - fine)


def test_small_load_finite_strain_estimator_is_the_linear_elastic_one():
    """δ = 0.002 R, 2 levels: neo-Hookean and linear elastic pairs have the same DoFs per
    level, η to 1 % and the force to 1 % (measured 0.32 % and 0.18 %): the current normal
    and the surface stretch of the interface terms tend to the reference ones."""
    small = ["constants.delta=0.002"]
    linear, finite = levels(*small, max_levels=2), levels(*small, *NEO_HOOKEAN, max_levels=2)
    assert [r["dofs"] for r in finite] == [r["dofs"] for r in linear]
    np.testing.assert_allclose(column(finite, "eta"), column(linear, "eta"), rtol=0.01)
    np.testing.assert_allclose(column(finite, "force"), column(linear, "force"), rtol=0.01)


def test_dorfler_force_converges_for_a_neo_hookean_sphere_on_a_block():
    """δ = 0.05 R, 3 levels: η falls, the force decreases with each level by less each time
    (measured 2.2256, 2.0940, 2.0178), the slave and master forces balance to 1e-8."""
    rows = levels("constants.delta=0.05", *NEO_HOOKEAN)
    assert np.all(np.diff(column(rows, "eta")) < 0)
    change = -np.diff(column(rows, "force"))
    assert np.all(change > 0) and change[1] < 0.8 * change[0]
    assert np.all(column(rows, "balance") < 1e-8)


def _read(path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.mpi
@pytest.mark.parametrize("model", ["elasticity", "neo_hookean"])
def test_cli_adaptive_pairs_in_3d_serial_equals_two_ranks(tmp_path, model):
    """The CLI on the coarse sphere on a block, 2 Dörfler levels, small and finite strain
    (δ = 0.02 R), serially and on 2 ranks: exit 0, η falls; the same DoFs per level, η and
    the forces (steps.csv of the load path, summary.json without one) to 1e-8."""
    sets = [*COARSE, "adapt.max_levels=2", "output.png=false"]
    if model == "neo_hookean":
        sets += [*NEO_HOOKEAN, "constants.delta=0.02"]
    args = ["run", str(SPHERE), "-q", *(a for s in sets for a in ("--set", s))]
    runs = {}
    for ranks in (0, 2):
        out = tmp_path / f"np{ranks}"
        proc = cli(tmp_path, *args, "-o", str(out), ranks=ranks)
        assert proc.returncode == 0, proc.stderr[-2000:]
        rows = _read(out / "convergence.csv")
        eta = [float(r["eta"]) for r in rows]
        assert len(rows) == 2 and eta[1] < eta[0]
        if (out / "steps.csv").exists():  # a load path: its steps' forces
            force = [float(r["contact_force"]) for r in _read(out / "steps.csv")]
        else:
            force = [json.loads((out / "summary.json").read_text())["contact_force"]]
        runs[ranks] = ([int(r["dofs"]) for r in rows], eta, force)
    (d0, e0, f0), (d2, e2, f2) = runs[0], runs[2]
    assert d0 == d2
    np.testing.assert_allclose(e2, e0, rtol=1e-8)
    np.testing.assert_allclose(f2, f0, rtol=1e-8)
