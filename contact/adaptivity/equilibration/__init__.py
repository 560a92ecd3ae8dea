"""Equilibrated fluxes and guaranteed error bounds (issue 30, docs/theory.md §9).

* :mod:`.reference` — reference-cell tables (basix RT_p, P_p, facet moments);
* :mod:`.cells` — the per-cell data rows and their exchange between ranks;
* :mod:`.operators` — the hybridized cell operators of a patch problem;
* :mod:`.patches` — the vertex-patch problems, batched by size;
* :mod:`.flux` — :func:`reconstruct_flux`, σ_h ∈ RT_p from plain inputs;
* :mod:`.bound` — the guaranteed bound for the scalar Signorini and obstacle problems.
"""

from .flux import Flux, FluxData, reconstruct_flux

__all__ = ["Flux", "FluxData", "reconstruct_flux"]
