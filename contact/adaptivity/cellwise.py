"""Cellwise terms of an estimator, T ↦ ∫ (term) w over the cell (and its facets), assembled
together.

An estimator's terms are UFL forms linear in one DG0 test function w.  Assembled one at a
time, each pays its own pass over the cells: the geometry, the packed coefficients and
the subexpressions the terms share (∇u_h, an obstacle's ψ at the quadrature points) are
computed once per term.  :func:`assemble_terms` assembles them as one form: w of term i
replaced by the i-th component of a test function of the blocked space DG0^n, so one pass
over the cells (one kernel per integral type and quadrature rule) fills all n columns.
Each column is the same integral as its own assembly, in the same quadrature.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem, la

#: assemble an estimator's terms as one form (:func:`assemble_terms`); False: one assembly
#: per term, the plain path (the same numbers to round-off; kept to measure the gain)
MERGED = True


def assemble_terms(terms: dict[str, ufl.Form], merged: bool | None = None) -> dict[str, np.ndarray]:
    """The vectors of the DG0 forms ``terms`` (each linear in a DG0 test function w on one mesh),
    interior-facet and ghost contributions summed into their owners: name ↦ the values of
    the owned and ghost cells (ghosts updated).  ``merged``: one assembly of the blocked
    form (default :data:`MERGED`) or one per term.  Collective."""
    merged = MERGED if merged is None else merged
    forms = list(terms.values())
    tests = [form.arguments()[0] for form in forms]  # a DG0 test function each
    meshes = {id(w.ufl_function_space().mesh) for w in tests}
    if not merged or len(forms) < 2 or len(meshes) > 1:
        return {name: _assembled(form, 1)[:, 0] for name, form in terms.items()}
    mesh = tests[0].ufl_function_space().mesh
    blocked = fem.functionspace(mesh, ("DG", 0, (len(forms),)))
    v = ufl.TestFunction(blocked)
    total = sum(ufl.replace(form, {w: v[i]}) for i, (w, form) in enumerate(zip(tests, forms)))
    values = _assembled(total, len(forms))
    return {name: values[:, i].copy() for i, name in enumerate(terms)}


def _assembled(form, columns: int) -> np.ndarray:
    """(local cells, columns): the DG0 vector of ``form``, reverse-scattered and updated."""
    vec = fem.assemble_vector(fem.form(form))
    vec.scatter_reverse(la.InsertMode.add)  # interior facets on rank boundaries
    vec.scatter_forward()
    return vec.array.reshape(-1, columns)
