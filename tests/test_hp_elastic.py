"""hp for an elastic body (contact.hp.elastic, docs/guide/hp.md): V_hp^d with Q ⊗ I_d; the rigid
motions are the near-nullspace through Q; on the Hertz 2D scene the hp loop brings the
contact half-width a and the peak pressure p0 within 0.5 % of Hertz theory at fewer
unknowns than the h-adaptive P1 loop; ``contact run`` with ``adapt.strategy: hp`` gives the
same levels on 1 and 2 ranks."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import contact
from contact.base.errors import ConfigError
from contact.hp.elastic import hp_elastic_problem
from contact.hp.space import HPSpace
from contact.models.physics import epsilon
from contact.post.hertz import compare

import numpy as np
import pytest
import ufl
from clirun import ROOT, h5_field
from clirun import contact as cli
from dolfinx import fem

HERTZ = ROOT / "configs" / "hertz_2d.yaml"
TARGET = 5e-3  # |a/a_H − 1| and |p0/p0_H − 1|


def test_rigid_motions_are_the_near_nullspace_through_q() -> None:
    """Each near-nullspace vector x of the hp problem is a rigid motion u = Q x (ε(u) = 0 to
    round-off) and a nonzero one; x = L u recovers it (L Q = I on V_hp^d)."""
    scene = contact.load_scene(HERTZ, ["output.verbose=false"])
    msh = scene.mesh
    n = msh.topology.index_map(2).size_local
    degrees = 1 + np.arange(n) % 4  # every degree 1 … 4, mixed across edges
    space = HPSpace(msh, 4, degrees)
    problem = hp_elastic_problem(scene, space)
    assert problem.near_nullspace is not None and problem.basis is not None
    u = fem.Function(problem.V)
    back = problem.b.duplicate()
    strain = fem.form(ufl.inner(epsilon(u), epsilon(u)) * ufl.dx)
    size = fem.form(ufl.inner(u, u) * ufl.dx)
    modes = problem.near_nullspace.getVecs()
    assert len(modes) == 3
    for x in modes:
        problem.basis.mult(x, u.x.petsc_vec)
        u.x.scatter_forward()
        norm = fem.assemble_scalar(size)
        assert norm > 1e-8  # the modes are orthonormal vectors of many entries
        assert fem.assemble_scalar(strain) <= 1e-20 * norm
        problem.basis_inverse.mult(u.x.petsc_vec, back)
        assert np.allclose(back.array_r, x.array_r, atol=1e-12)
    problem.destroy()


def _first_within(method: str, **options) -> tuple[int, float, float]:
    """(unknowns, a error, p0 error) of the first level of a Hertz run with both errors
    within TARGET."""
    scene = contact.load_scene(HERTZ, ["output.verbose=false"])
    found: list[tuple[int, float, float]] = []

    def on_level(lv) -> None:
        c = compare(lv.posed, lv.result, lv.scene.config.reference)
        found.append((lv.row()["dofs"], c.errors["a_error"], c.errors["p0_error"]))

    contact.adapt(scene, strategy=method, on_level=on_level, max_levels=8, **options)
    hit = next((f for f in found if abs(f[1]) <= TARGET and abs(f[2]) <= TARGET), None)
    assert hit is not None, (method, found)
    return hit


def test_hp_hertz_within_half_percent_at_fewer_unknowns_than_p1() -> None:
    n_hp, a_hp, p0_hp = _first_within("hp", p_max=4)
    n_p1, _, _ = _first_within("dorfler")
    assert n_hp < 0.75 * n_p1, (n_hp, n_p1)
    assert abs(a_hp) <= TARGET and abs(p0_hp) <= TARGET


def test_hp_elastic_refuses_what_it_does_not_do() -> None:
    friction = contact.load_scene(ROOT / "configs" / "friction_cylinder_2d.yaml")
    with pytest.raises(ConfigError, match="adapt.strategy: hp solves frictionless"):
        contact.adapt(friction, strategy="hp", max_levels=1)
    hyper = contact.load_scene(ROOT / "configs" / "hyperelastic_cylinder.yaml")
    with pytest.raises(ConfigError, match="adapt.strategy: hp solves the signorini and"):
        contact.adapt(hyper, strategy="hp", max_levels=1)


def _table(path: Path) -> list[dict]:
    with open(path) as f:
        return list(csv.DictReader(f))


def test_hp_hertz_scene_serial_equals_two_ranks(tmp_path: Path) -> None:
    """``contact run configs/hertz_2d.yaml`` with ``adapt.strategy: hp``: the same unknowns,
    cells, degrees and h/p decisions per level on 1 and 2 ranks, η to 1e-8, the same a and p0
    against Hertz, the contact force equal to the Dirichlet reaction, and the last level's
    ``degree`` cell field in its HDF5 file."""
    sets = ["adapt.strategy=hp", "adapt.p_max=3", "adapt.max_levels=4", "output.png=false"]
    args = [a for s in sets for a in ("--set", s)]
    tables, summaries = [], []
    for ranks in (0, 2):
        out = tmp_path / f"np{ranks}"
        proc = cli(tmp_path, "run", str(HERTZ), "-o", str(out), "-q", *args, ranks=ranks)
        assert proc.returncode == 0, proc.stderr
        tables.append(_table(out / "convergence.csv"))
        summaries.append(json.loads((out / "summary.json").read_text()))
    one, two = tables
    assert len(one) == len(two) == 4
    for a, b in zip(one, two):
        for key in ("dofs", "cells", "p_min", "p_max", "h_cells", "p_cells", "active_nodes"):
            assert a[key] == b[key], (key, a, b)
        assert abs(float(a["eta"]) - float(b["eta"])) <= 1e-8 * float(a["eta"])
    assert int(one[-1]["p_max"]) == 3
    for key in ("a_error", "p0_error"):
        assert abs(summaries[0][key] - summaries[1][key]) <= 1e-8, key
    for summary in summaries:
        assert summary["force_balance_error"] <= 1e-8
    degree = h5_field(tmp_path / "np0" / "solution_003.h5", "degree")
    assert len(degree), "no degree field in solution_003.h5"
    assert len(degree) == int(one[-1]["cells"]) and degree.max() == 3


def test_elastic_matrices_are_the_scalar_ones_per_component() -> None:
    """Q of V_hp^2 is Q_hp ⊗ I_2: row (i, a) holds Q_hp's row i on the columns (j, a)."""
    scene = contact.load_scene(HERTZ, ["output.verbose=false"])
    n = scene.mesh.topology.index_map(2).size_local
    space = HPSpace(scene.mesh, 3, 1 + np.arange(n) % 3)
    Qs, _ = space.matrices()
    Qv, _ = space.vector_matrices(2)
    x = Qs.createVecRight()
    x.array[:] = np.random.default_rng(0).standard_normal(len(x.array))
    xv = Qv.createVecRight()
    xv.array[0::2] = x.array
    xv.array[1::2] = -2.0 * x.array
    y, yv = Qs.createVecLeft(), Qv.createVecLeft()
    Qs.mult(x, y)
    Qv.mult(xv, yv)
    assert np.allclose(yv.array[0::2], y.array) and np.allclose(yv.array[1::2], -2.0 * y.array)
