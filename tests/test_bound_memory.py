"""What is alive during the guaranteed bound of an adaptive loop's last level.

1. The estimators' DG0 terms are assembled a block of cells at a time (cellwise.BLOCK_CELLS;
   facet terms after them, whole): no assembly of the terms packs more than a block of
   cells, and η, η_T, the terms and the parts are bit for bit those of the old path.
2. A releasing loop destroys the last level's operator K before its bound
   (adaptive.SHED_BOUND), whether the bound follows the residual indicators or is the
   level's only estimate (adaptive.PREDICT_BOUND): no PETSc matrix is alive when the bound
   runs, and the figures are those of the old path; the files ``contact run`` writes of
   that level are the same.
"""

from __future__ import annotations

import sys
from pathlib import Path

import contact
from contact.adaptivity import cellwise
from contact.adaptivity.equilibration import bound
from contact.adaptivity.estimate import estimate
from contact.drivers import adaptive

import numpy as np
import pytest
import ufl
from clirun import ROOT, pytest_on_ranks
from dolfinx import fem

SCENES = {
    "A_P1": ("signorini_free_boundary.yaml", []),  # B on the contact facets: a facet term
    "A_P2": ("signorini_free_boundary.yaml", ["mesh.degree=2", "mesh.cells=[8,4]"]),
    "ex9": ("peers/petsc_ex9.yaml", ["mesh.cells=[8,8]"]),  # the obstacle's cross term X
}


def _cells_of(form: ufl.Form, owned: int) -> int:
    """The cells a form's cell integrals integrate over (all owned ones for ``dx``)."""
    cells: set[int] = set()
    for itg in form.integrals_by_type("cell"):
        if itg.subdomain_id() in ("everywhere", "otherwise"):
            cells.update(range(owned))
        else:
            for _, some in itg.subdomain_data():
                cells.update(some.tolist())
    return len(cells)


@pytest.mark.parametrize("name", list(SCENES))
def test_the_bounds_terms_are_assembled_in_blocks(name: str, monkeypatch) -> None:
    """The bound's terms a block of cells at a time (cellwise.BLOCK_CELLS = owned cells / 5):
    each assembly of the merged terms integrates at most a block of cells, every cell once
    (one assembly of every cell on the old path), and η, η_T, the terms and the parts are
    bit for bit the old path's."""
    path, sets = SCENES[name]
    scene = contact.load_scene(ROOT / "configs" / path, [*sets, "output.verbose=false"])
    result = contact.solve(scene, verbose=False)
    msh = result.u_h.function_space.mesh
    n = msh.topology.index_map(msh.topology.dim).size_local
    block = max(1, n // 5)
    packed: list[int] = []  # the cells of each assembly of the merged terms
    real_form = fem.form

    def form(ufl_form, *args, **kwargs):
        if isinstance(ufl_form, ufl.Form) and ufl_form.arguments()[0].ufl_shape:  # DG0^n
            packed.append(_cells_of(ufl_form, n))
        return real_form(ufl_form, *args, **kwargs)

    monkeypatch.setattr(cellwise.fem, "form", form)
    out = {}
    for new in (False, True):
        monkeypatch.setattr(cellwise, "BLOCK_CELLS", block if new else None)
        packed.clear()
        out[new] = bound.guaranteed_bound(result.problem, result)
        if new:
            assert max(packed) <= block < n
            assert sum(packed) == n  # every cell once
        else:
            assert packed == [n]
    old, new = out[False], out[True]
    assert new.eta == old.eta > 0
    assert np.array_equal(new.eta_T.x.array, old.eta_T.x.array)
    assert new.terms == old.terms and new.parts == old.parts
    assert sum(v > 0 for v in new.terms.values()) >= 3


@pytest.mark.mpi
def test_the_bounds_terms_in_blocks_on_two_ranks() -> None:
    """The test above on each of 2 MPI ranks, whose blocks differ in size (each rank's owned
    cells / 5) and number (as many on every rank: a form is compiled collectively)."""
    proc = pytest_on_ranks(__file__, "assembled_in_blocks")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert proc.stdout.count("3 passed") == 2 and " failed" not in proc.stdout


def test_blocks_of_cells_give_a_forms_vector_with_its_facet_terms(monkeypatch) -> None:
    """cellwise.assemble_terms with ``block``: a form with cell terms over every cell, cell
    terms over tagged cells and exterior- and interior-facet terms, merged or one per term,
    in blocks of 7 cells (many blocks) is the vector of one assembly, bit for bit."""
    from dolfinx import mesh as dmesh
    from mpi4py import MPI

    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 9, 7)
    n = msh.topology.index_map(2).size_local
    V = fem.functionspace(msh, ("Lagrange", 2))
    u = fem.Function(V)
    u.interpolate(lambda x: np.sin(3 * x[0]) * x[1] ** 2 + x[0])
    w = ufl.TestFunction(fem.functionspace(msh, ("DG", 0)))
    some = np.arange(0, n, 3, dtype=np.int32)
    dx1 = ufl.Measure("dx", domain=msh, subdomain_data=[(4, some)], subdomain_id=4)
    h = ufl.CellDiameter(msh)
    jump = ufl.jump(ufl.grad(u), ufl.FacetNormal(msh))
    terms = {
        "volume": ufl.inner(ufl.grad(u), ufl.grad(u)) * w * ufl.dx,
        "quadrature": u**2 * w * ufl.dx(metadata={"quadrature_degree": 7}) + u * w * dx1,
        "boundary": u * w * ufl.ds,
        "jump": h("+") * jump**2 * ufl.avg(w) * ufl.dS,
    }
    for merged in (True, False):
        whole = cellwise.assemble_terms(terms, merged=merged, block=0)
        blocks = cellwise.assemble_terms(terms, merged=merged, block=7)
        for key in terms:
            assert np.array_equal(blocks[key], whole[key]), (merged, key)
            assert np.abs(whole[key]).max() > 0


#: ex9 on 8 × 8, the bound on the last level (of 3), its files written after the loop
SETS = (
    "mesh.cells=[8,8]",
    "adapt.indicators=residual",
    "adapt.max_levels=3",
    "output.levels=last",
    "output.png=false",
)


@pytest.mark.parametrize("name", ["A_P1", "A_P2", "ex9"])
def test_the_residual_estimate_in_blocks_of_cells_is_one_assembly(name: str, monkeypatch) -> None:
    """The residual estimator's terms (cells, and the jumps on interior facets after them)
    with cellwise.BLOCK_CELLS = owned cells / 5: each assembly of cell terms over every
    cell integrates at most a block, and η, η_T and the terms are those of one assembly
    (BLOCK_CELLS None), bit for bit."""
    from contact.adaptivity.estimate import residual_estimate

    path, sets = SCENES[name]
    scene = contact.load_scene(ROOT / "configs" / path, [*sets, "output.verbose=false"])
    result = contact.solve(scene, verbose=False)
    msh = result.u_h.function_space.mesh
    n = msh.topology.index_map(msh.topology.dim).size_local
    packed: list[int] = []
    real_form = fem.form

    def form(ufl_form, *args, **kwargs):
        if isinstance(ufl_form, ufl.Form) and ufl_form.integrals_by_type("cell"):
            packed.append(_cells_of(ufl_form, n))
        return real_form(ufl_form, *args, **kwargs)

    monkeypatch.setattr(cellwise.fem, "form", form)
    out = {}
    for block in (None, max(1, n // 5)):
        monkeypatch.setattr(cellwise, "BLOCK_CELLS", block)
        packed.clear()
        out[block] = residual_estimate(result.problem, result)
        assert max(packed) == n if block is None else max(packed) <= block < n
    old, new = out.values()
    assert new.eta == old.eta > 0
    assert np.array_equal(new.eta_T.x.array, old.eta_T.x.array)
    assert new.terms == old.terms


WRAPPER = """
import sys
import contact, contact.app.cli
from contact.drivers import adaptive

adaptive.SHED_BOUND = sys.argv[1] == "shed"
estimate = adaptive.estimate

def spied(problem, result, kind="residual"):  # whether K is alive at each bound, in bound.txt
    if kind != "residual":
        with open("bound.txt", "a") as out:
            out.write(f"{sys.argv[1]} {result.dofs} {bool(problem.K.handle)}\\n")
    return estimate(problem, result, kind)

adaptive.estimate = spied
sys.exit(contact.app.cli.main(sys.argv[2:]))
"""


@pytest.mark.parametrize("predict", [True, False])
def test_the_last_level_sheds_its_operator_before_its_bound(
    tmp_path: Path, monkeypatch, predict: bool
) -> None:
    """ex9 with the residual indicators (the bound on the last level only), releasing: K of
    the last level is destroyed when its bound runs (alive on the old path) and no PETSc
    matrix is left; its nodal contact force K x − b is kept as it was, and η, the error and
    the rows are those of the old path.  The last level's bound follows its residual
    indicators, or is its only estimate (``predict``: PREDICT_BOUND)."""
    from contact.setup import run as loop
    from contact.solvers.result import owned_residual

    monkeypatch.setattr(adaptive, "PREDICT_BOUND", predict)
    runs = {}
    for shed in (False, True):
        scene = contact.load_scene(  # a scene per run: the loop stows its first level's mesh
            ROOT / "configs" / "peers" / "petsc_ex9.yaml",
            ["output.verbose=false", "adapt.indicators=residual", "mesh.cells=[8,8]"],
        )
        monkeypatch.setattr(adaptive, "SHED_BOUND", shed)
        seen: dict = {}

        def spied(problem, result, kind="residual", seen=seen):
            if kind != "residual":  # the bound (no tol: on the last level only)
                seen["dofs"] = result.dofs
                seen["K"] = bool(problem.K.handle)
                seen["mats"] = _live_matrices()
                seen["force"] = owned_residual(result)
            return estimate(problem, result, kind)

        def on_level(level, seen=seen):  # K x − b while the level is whole, or as kept
            seen[level.index] = owned_residual(level.result)

        monkeypatch.setattr(adaptive, "estimate", spied)
        run = loop.adapt(scene, max_levels=3, keep=lambda lv: False, on_level=on_level)
        assert len(run.levels) == 3 and run.levels[-1].estimator == "equilibrated"
        assert seen["dofs"] == run.levels[-1].result.dofs
        assert seen["K"] is not shed
        assert (seen["mats"] == 0) is shed
        assert np.array_equal(seen["force"], seen[2])
        runs[shed] = ([(r["dofs"], r["eta"], r["error"]) for r in run.rows], seen[2])
        del run  # its levels' matrices are not counted in the next run
    assert runs[True][0] == runs[False][0]
    assert np.array_equal(runs[True][1], runs[False][1])


def _live_matrices() -> int:
    """PETSc matrices alive in Python (found by the garbage collector)."""
    import gc

    from petsc4py import PETSc

    gc.collect()
    return sum(1 for o in gc.get_objects() if isinstance(o, PETSc.Mat) and o.handle)


def test_the_files_of_a_last_level_shed_before_its_bound_are_the_same(tmp_path: Path) -> None:
    """``contact run`` of ex9 with the residual indicators and ``output.levels: last``: the
    files of the last level, written after its bound from the level whose K was destroyed
    before it (bound.txt: K at each bound), are those of the old path (K whole): contact.csv
    byte for byte, every HDF5 dataset, convergence.csv and summary.json but for clocks."""
    import csv
    import json
    import os
    import subprocess

    import h5py

    (tmp_path / "wrapper.py").write_text(WRAPPER)
    config = ROOT / "configs" / "peers" / "petsc_ex9.yaml"
    for mode in ("shed", "keep"):
        cmd = [sys.executable, str(tmp_path / "wrapper.py"), mode, "run", str(config)]
        cmd += ["-o", mode, "-q"]
        for item in SETS:
            cmd += ["--set", item]
        env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONWARNINGS": "ignore"}
        proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env)
        assert proc.returncode == 0, proc.stderr
    bounds = (tmp_path / "bound.txt").read_text().split()
    assert bounds[0::3] == ["shed", "keep"]  # one bound per run, the last level's
    assert bounds[2::3] == ["False", "True"]  # its K
    shed, keep = (tmp_path / m for m in ("shed", "keep"))
    names = sorted(p.name for p in shed.iterdir())
    assert names == sorted(p.name for p in keep.iterdir())
    assert (shed / "contact.csv").read_bytes() == (keep / "contact.csv").read_bytes()
    for h5 in sorted(keep.glob("*.h5")):
        keys = _datasets(h5)
        assert keys
        with h5py.File(h5) as a, h5py.File(shed / h5.name) as b:
            for key in keys:
                assert np.array_equal(a[key][()], b[key][()], equal_nan=True), (h5.name, key)
    rows = [list(csv.DictReader(open(f / "convergence.csv"))) for f in (shed, keep)]
    figures = [{k: v for k, v in r.items() if not _clock(k)} for r in rows[0]]
    assert figures == [{k: v for k, v in r.items() if not _clock(k)} for r in rows[1]]
    assert len(rows[0]) == 3
    a, b = (json.loads((f / "summary.json").read_text()) for f in (shed, keep))
    assert {k: v for k, v in a.items() if not _clock(k)} == {
        k: v for k, v in b.items() if not _clock(k)
    }


def _clock(key: str) -> bool:
    """A column or key of wall or CPU seconds (a run's clocks, never equal)."""
    return any(part in key for part in ("time", "seconds", "wall", "cpu"))


def _datasets(h5: Path) -> list[str]:
    import h5py

    keys: list[str] = []
    with h5py.File(h5) as f:
        f.visititems(lambda k, o: keys.append(k) if isinstance(o, h5py.Dataset) else None)
    return keys
