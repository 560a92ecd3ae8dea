"""Cellwise terms of an estimator, T ↦ ∫ (term) w over the cell (and its facets), assembled
together.

An estimator's terms are UFL forms linear in one DG0 test function w.  Assembled one at a
time, each pays its own pass over the cells: the geometry, the packed coefficients and
the subexpressions the terms share (∇u_h, an obstacle's ψ at the quadrature points) are
computed once per term.  :func:`assemble_terms` assembles them as one form: w of term i
replaced by the i-th component of a test function of the blocked space DG0^n, so one pass
over the cells (one kernel per integral type and quadrature rule) fills all n columns.
Each column is the same integral as its own assembly, in the same quadrature.

An assembly packs the coefficients of every cell at once (one row of their DoF values per
cell: ~18 numbers per cell for the guaranteed bound's terms of a P1 solution), a transient
that outgrows what the mesh itself holds.  The cell integrals over every cell are therefore
assembled :data:`BLOCK_CELLS` cells at a time into one vector, so that only a block's
coefficients are packed, and the other integrals (facets, tagged cells) after them, whole,
as one assembly adds them: each cell gets the same contributions in the same order, the
same numbers.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem, la
from mpi4py import MPI

#: assemble an estimator's terms as one form (:func:`assemble_terms`); False: one assembly
#: per term, the plain path (the same numbers to round-off; kept to measure the gain)
MERGED = True
#: the cell integrals over every cell assembled this many cells at a time (their packed
#: coefficients a block's); None: every cell at once, the old path (the same numbers)
BLOCK_CELLS: int | None = 2**17
#: the subdomain id of a block of cells
BLOCK_ID = 1


def assemble_terms(
    terms: dict[str, ufl.Form], merged: bool | None = None, block: int | None = None
) -> dict[str, np.ndarray]:
    """The vectors of the DG0 forms ``terms`` (each linear in a DG0 test function w on one mesh),
    interior-facet and ghost contributions summed into their owners: name ↦ the values of
    the owned and ghost cells (ghosts updated).  ``merged``: one assembly of the blocked
    form (default :data:`MERGED`) or one per term; ``block``: the cell integrals over every
    cell assembled this many cells at a time (default :data:`BLOCK_CELLS`; 0: all at once).
    Collective."""
    merged = MERGED if merged is None else merged
    block = BLOCK_CELLS if block is None else block
    forms = list(terms.values())
    tests = [form.arguments()[0] for form in forms]  # a DG0 test function each
    meshes = {id(w.ufl_function_space().mesh) for w in tests}
    if not merged or len(forms) < 2 or len(meshes) > 1:
        return {name: _assembled(form, 1, block)[:, 0] for name, form in terms.items()}
    mesh = tests[0].ufl_function_space().mesh
    blocked = fem.functionspace(mesh, ("DG", 0, (len(forms),)))
    v = ufl.TestFunction(blocked)
    total = sum(ufl.replace(form, {w: v[i]}) for i, (w, form) in enumerate(zip(tests, forms)))
    values = _assembled(total, len(forms), block)
    return {name: values[:, i].copy() for i, name in enumerate(terms)}


def _assembled(form: ufl.Form, columns: int, block: int | None) -> np.ndarray:
    """(local cells, columns): the DG0 vector of ``form``, reverse-scattered and updated;
    ``block``: cells per block (None or 0: all at once)."""
    space = form.arguments()[0].ufl_function_space()
    msh = space.mesh
    n = msh.topology.index_map(msh.topology.dim).size_local
    everywhere = [
        i
        for i in form.integrals()
        if i.integral_type() == "cell" and i.subdomain_id() in ("everywhere", "otherwise")
    ]
    # as many blocks on every rank: a form is compiled collectively
    blocks = 1 if not block or not everywhere else msh.comm.allreduce(-(-n // block), MPI.MAX)
    if blocks <= 1:
        vec = fem.assemble_vector(fem.form(form))
    else:
        vec = la.vector(space.dofmap.index_map, space.dofmap.index_map_bs)
        vec.array[:] = 0.0
        bounds = n * np.arange(blocks + 1) // blocks
        for start, stop in zip(bounds[:-1], bounds[1:]):  # owned cells, as dx integrates them
            cells = [(BLOCK_ID, np.arange(start, stop, dtype=np.int32))]
            part = [i.reconstruct(subdomain_id=BLOCK_ID, subdomain_data=cells) for i in everywhere]
            fem.assemble_vector(vec.array, fem.form(ufl.Form(part)))
        rest = [i for i in form.integrals() if all(i is not j for j in everywhere)]
        if rest:  # after the cells, as one assembly adds them
            fem.assemble_vector(vec.array, fem.form(ufl.Form(rest)))
    vec.scatter_reverse(la.InsertMode.add)  # interior facets on rank boundaries
    vec.scatter_forward()
    return vec.array.reshape(-1, columns)
