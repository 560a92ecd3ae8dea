"""Equilibrated fluxes and guaranteed error bounds (issue 30, docs/theory.md §9).

* :mod:`.reference` — reference-cell tables (basix RT_p, P_p, facet moments);
* :mod:`.cells` — the per-cell data rows and their exchange between ranks;
* :mod:`.operators` — the hybridized cell operators of a patch problem;
* :mod:`.patches` — the vertex-patch problems, batched by size (NumPy: ``backend="numpy"``);
* :mod:`.patches_c`, :mod:`.compiled` — the same patch problems in a C kernel
  (``kernels/eqlb.c``) compiled at first use into a verified cache (the default backend: ≈ 20×
  faster, the same σ_h to round-off), and there a cheaper P1 fit of the same constraints
  (``backend="flow"``);
* :mod:`.flux` — :func:`reconstruct_flux`, σ_h ∈ RT_p from plain inputs;
* :mod:`.bound` — the guaranteed bound for the scalar Signorini and obstacle problems.
"""

from .flux import Flux, FluxData, reconstruct_flux

__all__ = ["Flux", "FluxData", "reconstruct_flux"]
