"""High-degree fields (an hp level's) as the output formats carry them.

XDMF and VTK carry Lagrange fields up to degree :data:`OUTPUT_DEGREE` here (the output mesh
takes the fields' degree as its geometry degree, and the XDMF cell types stop at 2), while
an hp solution lives in P_{p_max}.  A level is written as the Lagrange interpolant of degree
:data:`OUTPUT_DEGREE` of each field: at the vertices (and, for even p_max, at the edge
midpoints, nodes of P_{p_max} too) the values are u_h's own nodal values; the cell field
``degree`` (``contact.hp.space.HPSpace.degree_function``) shows where the degrees went.  The
P_{p_max} coefficients stay available from Python (``level.result.u_h``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from dolfinx import fem

#: the Lagrange degree an hp level's point fields are written at
OUTPUT_DEGREE = 2


def output_fields(fields: Sequence[fem.Function]) -> list[fem.Function]:
    """The Lagrange interpolants of degree :data:`OUTPUT_DEGREE` of ``fields`` (same names).

    A NaN of a field (the gap off Γ_C) stays NaN at the output nodes it reaches and at no
    others: the field is interpolated with NaN read as 0, and an output node is NaN where
    the interpolant of the NaN indicator is nonzero.  Fields of degree ≤ the output degree
    are returned as they are.  Collective.
    """
    out = []
    spaces: dict[tuple, fem.FunctionSpace] = {}
    for fn in fields:
        V = fn.function_space
        if V.element.basix_element.degree <= OUTPUT_DEGREE:
            out.append(fn)
            continue
        key = (V.mesh, V.value_shape)
        if key not in spaces:
            spaces[key] = fem.functionspace(V.mesh, ("Lagrange", OUTPUT_DEGREE, V.value_shape))
        W = spaces[key]
        nan = np.isnan(fn.x.array)
        src = fem.Function(V)
        src.x.array[:] = np.where(nan, 0.0, fn.x.array)
        copy = fem.Function(W, name=fn.name)
        copy.interpolate(src)
        if fn.x.index_map.comm.allreduce(bool(nan.any())):
            src.x.array[:] = nan.astype(float)
            hit = fem.Function(W)
            hit.interpolate(src)
            copy.x.array[np.abs(hit.x.array) > 1e-12] = np.nan
        out.append(copy)
    return out
