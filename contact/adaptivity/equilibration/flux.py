"""Equilibrated flux reconstruction (Ern & Vohralík 2015) for a scalar problem with a
contact multiplier: the public entry point :func:`reconstruct_flux`.

Given u_h ∈ P_p, the data f, k, t (Γ_N), t_C (Γ_C) and where the multiplier lives (Γ_C,
Ω or nowhere), it returns σ_h ∈ RT_p with, exactly up to round-off,

    −div σ_h = Π_p f + λ̃_h     in every cell   (λ̃_h = 0 unless the multiplier is in Ω),
    σ_h·n = Π_p t   on Γ_N,    σ_h·n = Π_p t_C + λ̃_h   on Γ_C,    σ_h·n = 0 on other
    exterior facets but Γ_D,

where λ̃_h = κ B⁻(λ_h) is the given discrete multiplier λ_h, where it changes sign between
its nodes (P2) replaced by a function of one sign with the same lumped moments
(:mod:`.multiplier`).  It does not look at a configuration: the
inputs are DOLFINx functions, UFL expressions and facet tags (:class:`FluxData`), so the
same reconstruction serves other models (row-wise for elasticity).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import basix.ufl
import numpy as np
from dolfinx import fem
from mpi4py import MPI

from .cells import (
    CONTACT,
    CellTable,
    FluxData,
    cell_source,
    complete,
    deferred_table,
    return_to_owners,
)
from .compiled import library
from .multiplier import clipped, shares
from .operators import cell_rule, facet_rule
from .patches import PatchOutput, solve_patches
from .patches_c import solve_patches_compiled
from .reference import Reference, reference

__all__ = ["Flux", "FluxData", "reconstruct_flux"]

#: the patch solver: "compiled" (the C kernel of :mod:`.patches_c`), "numpy" (:mod:`.patches`,
#: the reference implementation, kept to measure and cross-check the kernel) or "flow" (P1
#: only, compiled: the same constraints and so the same guarantee, the patch minimization only
#: approximated — block coordinate descent in the facet moments, the constant fluxes under the
#: constraints, then ``rounds`` times the higher moments facet by facet and the constant
#: fluxes again; ``solve_flow`` in ``kernels/eqlb.c``)
BACKENDS = ("compiled", "numpy", "flow")
#: ``degree=0`` for a P1 solution: σ_h ∈ RT_0 (Braess & Schöberl 2008), each patch's target
#: the RT_0 interpolant of ψ_a τ (τ: k∇u_h or the given target, its cell mean), so that
#: the targets still sum to τ; Π_0 of the data and of λ̃_h, and osc_T adds the multiplier's
#: rest λ̃_h − Π_0 λ̃_h (:func:`_multiplier_oscillation`).  A third of the unknowns of RT_1
#: per patch; in 3D at 520k DoFs the patch problems 5.5× cheaper (cost_3d.csv of
#: demos/results/equilibrated/), a larger η (docs/theory.md §9).
LOWEST = 0
#: the default rounds of the "flow" backend (docs/theory.md §9: effectivity against cost)
FLOW_ROUNDS = 1
#: serially, the compiled patches are solved a block of vertices at a time, with the cells
#: of about this many per block whole in the table (the flux data t and the target τ at the
#: quadrature points are most of its memory, ~300 of its ~430 bytes per cell for P1 in 2D);
#: None: the whole table at once (the old path, and the parallel one)
BLOCK_CELLS: int | None = 65536
#: the rows of each block of vertices found by one stable sort of the table's vertices by
#: block (linear in the cells); False: a pass over the whole table per block (the plain path,
#: quadratic in the cells: the blocks are ~cells / :data:`BLOCK_CELLS`); the same rows
SORTED_BLOCKS = True
#: with blocks, the table itself is made a block at a time (:class:`.cells.CellSource`: no
#: column for every cell at once; λ̃_h's functions and osc_T also a block at a time); False:
#: the table whole but for t and τ, the old path (the same numbers)
BLOCK_TABLE = True
#: P1 (no edge coefficients to remove): κ = 1 and no bubble set directly, as :func:`.shares`
#: returns them; False: through :func:`.shares` over every contact entity, the plain path
P1_SHORTCUT = True
#: with blocks, P1 and the multiplier's rule of :func:`.shares` (κ = 1, no bubble) and a flux
#: of u_h's degree (no multiplier oscillation): λ_h clipped set on the whole array of its
#: nodal values at once (the clipping is nodewise), with no second pass over the blocks'
#: rows; False: the rows made again a block at a time for it (the plain path, the same
#: numbers)
NODAL_MULTIPLIER = True
#: where κ = 1 and there is no bubble (P1, the rule of :func:`.shares`), :attr:`Flux.lmbda` is
#: λ_h clipped itself, so the bound's forms pack neither κ nor the bubble (κ (λ − ½·0) with
#: κ = 1 is λ exactly); False: κ (λ_h clipped − ½ bubble) always, the plain path
UNIT_KAPPA = True


@dataclass
class Flux:
    """The reconstruction: σ_h (RT_p), the multiplier λ̃_h it carries (:attr:`lmbda`), the data
    oscillation of each owned cell,

        osc_T = k_T,min^{-1/2} ( h_T/π ‖f − Π_p f‖_T + Σ_{F ⊂ ∂T, t given} C_{T,F} ‖t − Π_p t‖_F ),
        C_{T,F} = h_T ((|F| / |T|)(1/π² + 2/(dπ)))^{1/2},

    (so that (f − Π_p f, v)_T + ⟨t − Π_p t, v⟩_{∂T} ≤ osc_T ‖k^{1/2}∇v‖_T for every v ∈ H¹(T):
    Poincaré's h_T/π on convex cells, and the trace inequality of :func:`oscillation`),
    the projected balance defect (algebraic residual, flux units) and timings (seconds).
    :attr:`sigma_cells`, the same field cell by cell in vector DG_{p+1} (no continuity
    imposed; σ_h is its RT_p interpolant), is built when first asked for."""

    sigma_h: fem.Function
    lmbda_clip: fem.Function  # λ_h with wrong-signed nodal values clipped (the element of u_h)
    bubble: fem.Function  # Σ_e β_e φ_{m_e}: the removed Bernstein coefficients (P2)
    kappa: fem.Function  # DG0: κ of the cell's contact entity (the largest of its facets')
    osc: np.ndarray  # (owned cells,) osc_T
    defect: float
    seconds: dict = field(default_factory=dict)
    cells: Callable[[], fem.Function] | None = field(default=None, repr=False)
    unit: bool = False  # κ = 1 and no bubble on every cell (P1, the rule of .shares)

    @cached_property
    def sigma_cells(self) -> fem.Function:
        assert self.cells is not None  # set by reconstruct_flux
        return self.cells()

    @property
    def lmbda(self):
        """λ̃_h = κ (λ_h − ½ Σ_e β_e φ_{m_e}) as UFL on the contact entities (Γ_C facets or Ω;
        on a cell with two contact facets an upper bound of |λ̃_h|; λ_h clipped itself where κ = 1
        and there is no bubble, with :data:`UNIT_KAPPA`)."""
        if self.unit and UNIT_KAPPA:
            return self.lmbda_clip
        return self.kappa * (self.lmbda_clip - 0.5 * self.bubble)


def reconstruct_flux(
    data: FluxData,
    multiplier: str | None = None,
    sign: float = 0.0,
    backend: str = "compiled",
    rounds: int = FLOW_ROUNDS,
    degree: int | None = None,
) -> Flux:
    """σ_h of the module docstring.  ``multiplier``: None, "facets" (λ on the ``contact``
    facets, Signorini) or "cells" (λ in Ω, obstacle); ``sign``: the sign λ̃ must have
    (−1: ≤ 0, +1: ≥ 0, 0: any); ``backend``: one of :data:`BACKENDS`; ``rounds``: those of
    the "flow" backend (≥ 0); ``degree``: that of σ_h ∈ RT_degree, None for p, the degree
    of u_h (Ern & Vohralík: robust in p), or 0 for P1, the lowest order (:data:`LOWEST`).
    Collective."""
    if multiplier not in (None, "facets", "cells"):
        raise ValueError(f"multiplier: expected None, 'facets' or 'cells', got {multiplier!r}")
    if backend not in BACKENDS:
        raise ValueError(f"backend: expected one of {BACKENDS}, got {backend!r}")
    V = data.u_h.function_space
    msh = V.mesh
    d = msh.topology.dim
    p = V.element.basix_element.degree
    q = p if degree is None else degree
    if q < p and (p, q) != (1, 0):
        raise ValueError(
            f"degree: {p} (that of u_h) or, for P1, 0 (the lowest order), or more than {p} "
            f"(a richer flux), got {q}"
        )
    ref = reference(d, q, p)
    if backend == "flow" and (p != 1 or q != 1 or rounds < 0):
        raise ValueError(
            f"backend 'flow': P1, degree 1 and rounds >= 0 only, got P{p}, {q} and {rounds}"
        )
    comm = msh.comm
    clock = _Clock()
    if multiplier is not None and data.lmbda_h is None:
        raise ValueError("lmbda_h: the discrete multiplier is needed when the flux carries one")
    DG0 = fem.functionspace(msh, ("DG", 0))
    vmap = msh.topology.index_map(0)
    # None where the kernel cannot be had (no C compiler, say): the NumPy solver, the same
    # numbers, slower (compiled.load has warned once)
    kernel = library(comm, ref, V.dofmap.list.shape[1]) if backend in ("compiled", "flow") else None
    compiled = kernel is not None
    n_cells = msh.topology.index_map(d).size_local
    blocks = comm.size == 1 and compiled and BLOCK_CELLS is not None and n_cells > BLOCK_CELLS
    if blocks and BLOCK_TABLE:
        assert kernel is not None  # blocks: compiled
        return _flux_in_blocks(data, kernel, ref, multiplier, sign, rounds, backend, DG0, clock)
    table, n_owned, boundary = deferred_table(data, ref, DG0, deferred=blocks)
    work, source = complete(comm, table, np.full(n_owned, comm.rank))
    clock.lap("gather")
    if blocks:
        assert kernel is not None  # blocks: compiled
        out, osc = _patches_in_blocks(
            kernel,
            lambda rows: boundary.fill(table.take(rows), rows),
            table.gvert,
            vmap.local_range,
            ref,
            multiplier,
            sign,
            rounds if backend == "flow" else -1,
        )
    elif kernel is not None:
        out, osc = solve_patches_compiled(
            comm,
            kernel,
            work,
            vmap.local_range,
            ref,
            multiplier,
            sign,
            flow=rounds if backend == "flow" else -1,
        )
        osc = osc[:n_owned]
    else:
        owned = np.arange(*vmap.local_range, dtype=np.int64)
        out = solve_patches(work, owned, ref, multiplier, sign)
    clock.lap("patches")
    offset = msh.topology.index_map(d).local_range[0]
    alpha = return_to_owners(comm, work.gcell, source, out.alpha, n_owned, offset)
    if compiled:
        sigma_h = rt_function(msh, ref, alpha)  # transforms alpha in place
        sigma_cells = None
    else:
        sigma_cells = cellwise(msh, ref, table, alpha)
        sigma_h = _interpolated(msh, ref, sigma_cells)
        osc = oscillation(table, ref)
    if data.multiplier_rule is None:
        lmbda_clip, bubble, kappa = multiplier_functions(V, table, ref, multiplier, sign, DG0)
    else:  # the rule's λ̃_h itself: κ = 1, no bubble
        lmbda_clip, bubble, kappa = _rule_functions(data, V, DG0)
    osc = osc + _multiplier_oscillation(table, ref, multiplier, sign)
    clock.lap("assemble")
    defect = comm.allreduce(out.defect)
    cells = (
        (lambda: sigma_cells)
        if sigma_cells is not None
        else (lambda: cellwise(msh, ref, table, rt_coefficients(sigma_h, n_owned)))
    )
    unit = data.multiplier_rule is None and P1_SHORTCUT and ref.pu == 1
    return Flux(sigma_h, lmbda_clip, bubble, kappa, osc, defect, clock.seconds, cells, unit)


def _patches_in_blocks(
    kernel,
    rows_of: Callable[[np.ndarray], CellTable],
    gvert: np.ndarray,
    vertices: tuple[int, int],
    ref: Reference,
    multiplier: str | None,
    sign: float,
    flow: int,
) -> tuple[PatchOutput, np.ndarray]:
    """:func:`.patches_c.solve_patches_compiled` of a serial table, a block of vertices at a
    time: the rows of the cells with a vertex in the block (``gvert``: the cells' global
    vertices) are made whole by ``rows_of`` (:meth:`.cells.BoundaryRows.fill` of a deferred
    table, or :meth:`.cells.CellSource.rows`) and handed to the kernel, which adds each
    patch's share to α of its cells (α, the balance defect and the counters sum over the
    blocks; osc_T is a row's own).  The same patches as in one call, so σ_h agrees to
    round-off."""
    lo, hi = vertices
    n = len(gvert)
    blocks = max(1, -(-n // (BLOCK_CELLS or n)))
    bounds = lo + (hi - lo) * np.arange(blocks + 1) // blocks  # block b: bounds[b] … [b + 1]
    found = block_rows(gvert, bounds) if SORTED_BLOCKS else None
    alpha, osc = np.zeros((n, ref.m)), np.full(n, np.nan)
    defect, counters = 0.0, {"cell_evaluations": 0, "work_rows": 0}
    for b in range(blocks):
        v0, v1 = int(bounds[b]), int(bounds[b + 1])
        rows = (
            found[b]
            if found is not None
            else np.flatnonzero(np.any((gvert >= v0) & (gvert < v1), axis=1))
        )
        part = rows_of(rows)
        out, part_osc = solve_patches_compiled(
            MPI.COMM_SELF, kernel, part, (v0, v1), ref, multiplier, sign, flow=flow
        )
        alpha[rows] += out.alpha
        osc[rows] = part_osc
        defect += out.defect
        counters["cell_evaluations"] += out.stats["cell_evaluations"]
        counters["work_rows"] = max(counters["work_rows"], out.stats["work_rows"])
        del part, out, part_osc  # before the next block's rows are made
    return PatchOutput(alpha, defect, counters), osc


def block_rows(gvert: np.ndarray, bounds: np.ndarray) -> list[np.ndarray]:
    """The rows of the cells with a vertex in each block [bounds[b], bounds[b + 1]), in
    increasing order (as a scan of ``gvert`` per block finds them): one stable sort of the
    (cell, vertex) pairs by block, a cell listed once per block."""
    blocks = len(bounds) - 1
    small = np.int16 if blocks < np.iinfo(np.int16).max else np.int32  # int16: a radix sort
    block = (np.searchsorted(bounds, gvert.ravel(), side="right") - 1).astype(small)
    order = np.argsort(block, kind="stable")  # by block, then by cell
    cell, block = order // gvert.shape[1], block[order]
    first = np.ones(len(order), dtype=bool)  # a cell's first pair in its block
    first[1:] = (cell[1:] != cell[:-1]) | (block[1:] != block[:-1])
    cell, block = cell[first], block[first]
    starts = np.searchsorted(block, np.arange(blocks + 1))  # vertices outside: left out
    return [cell[starts[b] : starts[b + 1]] for b in range(blocks)]


def _flux_in_blocks(
    data: FluxData,
    kernel,
    ref: Reference,
    multiplier: str | None,
    sign: float,
    rounds: int,
    backend: str,
    DG0: fem.FunctionSpace,
    clock: _Clock,
) -> Flux:
    """:func:`reconstruct_flux` of a serial compiled run whose table is never whole: its rows
    are made a block at a time (:class:`.cells.CellSource`) for the patches, for λ̃_h's
    functions and for the multiplier's oscillation, each of which works row by row, so the
    numbers are those of the deferred table's blocks."""
    V = data.u_h.function_space
    msh = V.mesh
    source = cell_source(data, ref, DG0)
    n = len(source)
    clock.lap("gather")
    # serially the global vertex indices are the local ones
    lo, hi = msh.topology.index_map(0).local_range
    out, osc = _patches_in_blocks(
        kernel,
        source.rows,
        source.c2v.astype(np.int64) + lo if lo else source.c2v,
        (lo, hi),
        ref,
        multiplier,
        sign,
        rounds if backend == "flow" else -1,
    )
    clock.lap("patches")
    sigma_h = rt_function(msh, ref, out.alpha)  # transforms alpha in place
    if data.multiplier_rule is None:
        lmbda_clip, bubble = fem.Function(V, name="lambda_h"), fem.Function(V)
        kappa = np.ones(n)
    else:  # the rule's λ̃_h itself: κ = 1, no bubble
        lmbda_clip, bubble, kap = _rule_functions(data, V, DG0)
    step = BLOCK_CELLS or n
    points = multiplier is not None and ref.lowest  # k for the multiplier's oscillation
    nodal = (
        NODAL_MULTIPLIER
        and P1_SHORTCUT
        and ref.pu == 1
        and data.multiplier_rule is None
        and not points
    )
    if nodal:  # what the rows would give: κ = 1, no bubble, no multiplier oscillation
        if source.lam is not None:
            lmbda_clip.x.array[:] = clipped(source.lam.x.array, sign)
    for start in range(0, 0 if nodal else n, step):
        cells = np.arange(start, min(start + step, n), dtype=np.int32)
        part = source.rows(cells, boundary=False, points=points)
        if data.multiplier_rule is None:
            kappa[cells] = _multiplier_rows(
                V, part, cells, ref, multiplier, sign, lmbda_clip, bubble
            )
        osc[cells] += _multiplier_oscillation(part, ref, multiplier, sign)
        del part
    if data.multiplier_rule is None:
        for fn in (lmbda_clip, bubble):
            fn.x.scatter_forward()
        kap = fem.Function(DG0, name="kappa")
        kap.x.array[:n] = kappa
        kap.x.scatter_forward()
    clock.lap("assemble")
    return Flux(
        sigma_h,
        lmbda_clip,
        bubble,
        kap,
        osc,
        out.defect,
        clock.seconds,
        lambda: cellwise(
            msh,
            ref,
            source.rows(np.arange(n, dtype=np.int32), boundary=False),
            rt_coefficients(sigma_h, n),
        ),
        data.multiplier_rule is None and P1_SHORTCUT and ref.pu == 1,
    )


def _rule_functions(
    data: FluxData, V: fem.FunctionSpace, DG0: fem.FunctionSpace
) -> tuple[fem.Function, fem.Function, fem.Function]:
    """λ̃_h, the bubble and κ of a multiplier rule: its λ̃_h itself, κ = 1, no bubble."""
    kappa = fem.Function(DG0)
    kappa.x.array[:] = 1.0
    return data.multiplier_rule.function(), fem.Function(V), kappa


class _Clock:
    """Wall and CPU seconds of consecutive phases: seconds[name], seconds[name + "_cpu"]."""

    def __init__(self) -> None:
        self.seconds: dict = {}
        self.t, self.c = time.perf_counter(), time.process_time()

    def lap(self, name: str) -> None:
        t, c = time.perf_counter(), time.process_time()
        self.seconds[name], self.seconds[f"{name}_cpu"] = t - self.t, c - self.c
        self.t, self.c = t, c


def _rt_space(msh, ref: Reference) -> fem.FunctionSpace:
    return fem.functionspace(
        msh, basix.ufl.element("RT", msh.basix_cell(), ref.p + 1, basix.LagrangeVariant.legendre)
    )


def rt_function(msh, ref: Reference, alpha: np.ndarray) -> fem.Function:
    """σ_h ∈ RT_p from the reference coefficients ``alpha`` of the owned cells (σ_h|_T =
    Piola(Σ_l α_l φ̂_l)): the DoFs are α in DOLFINx's global orientation, u = T⁻ᵀ α (T: the
    cell's DoF transformation, as DOLFINx's interpolation applies it); a DoF shared by two
    cells takes one cell's value, which the other's equals to round-off (σ_h·n is
    continuous)."""
    RT = _rt_space(msh, ref)
    sigma_h = fem.Function(RT, name="sigma_h")
    n = len(alpha)
    if RT.element.needs_dof_transformations:
        msh.topology.create_entity_permutations()
        perms = msh.topology.get_cell_permutation_info()[:n]
        RT.element.Tt_inv_apply(alpha.reshape(-1), perms, 1)
    sigma_h.x.array[RT.dofmap.list[:n]] = alpha
    sigma_h.x.scatter_forward()
    return sigma_h


def rt_coefficients(sigma_h: fem.Function, n: int) -> np.ndarray:
    """The reference coefficients α = Tᵀ u of the first n cells (the inverse of
    :func:`rt_function`)."""
    RT = sigma_h.function_space
    alpha = sigma_h.x.array[RT.dofmap.list[:n]]
    if RT.element.needs_dof_transformations:
        msh = RT.mesh
        RT.element.Tt_apply(alpha.reshape(-1), msh.topology.get_cell_permutation_info()[:n], 1)
    return alpha


def _interpolated(msh, ref: Reference, sigma_cells: fem.Function) -> fem.Function:
    """σ_h in RT_p: the cellwise field interpolated by DOLFINx (exact where it is normal-
    continuous, which the patch problems make it)."""
    sigma_h = fem.Function(_rt_space(msh, ref), name="sigma_h")
    sigma_h.interpolate(sigma_cells)
    sigma_h.x.scatter_forward()
    return sigma_h


def cellwise(msh, ref: Reference, table: CellTable, alpha: np.ndarray) -> fem.Function:
    """The Piola-mapped RT_p coefficients ``alpha`` of the owned cells (rows of ``table``) in
    a vector DG_{p+1} space (exact: RT_p ⊂ P_{p+1}), no continuity imposed."""
    d, p = ref.d, ref.p
    W = fem.functionspace(msh, ("DG", p + 1, (d,)))
    W0 = fem.functionspace(msh, ("DG", p + 1))
    points = W0.element.basix_element.points
    phi = _rt_element(d, p).tabulate(0, points)[0]  # (npts, m, d)
    x = table.x
    J = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
    det = np.linalg.det(J)
    ref_vals = np.einsum("qmd,nm->nqd", phi, alpha)
    vals = np.einsum("nij,nqj->nqi", J, ref_vals) / det[:, None, None]
    sigma_dg = fem.Function(W)
    n = len(alpha)
    dofs = W0.dofmap.list[:n]
    sigma_dg.x.array.reshape(-1, d)[dofs] = vals
    sigma_dg.x.scatter_forward()
    return sigma_dg


def _rt_element(d: int, p: int):
    import basix

    from .reference import CELLS

    return basix.create_element(
        basix.ElementFamily.RT, CELLS[d], p + 1, basix.LagrangeVariant.legendre
    )


def multiplier_functions(V, table: CellTable, ref: Reference, multiplier, sign, DG0):
    """λ_h clipped, the Bernstein bubble and κ (:class:`Flux`) from the owned rows."""
    n = len(table)
    lmbda_clip, bubble = fem.Function(V, name="lambda_h"), fem.Function(V)
    kappa = _multiplier_rows(V, table, np.arange(n), ref, multiplier, sign, lmbda_clip, bubble)
    for fn in (lmbda_clip, bubble):
        fn.x.scatter_forward()
    kap = fem.Function(DG0, name="kappa")
    kap.x.array[:n] = kappa
    kap.x.scatter_forward()
    return lmbda_clip, bubble, kap


def _multiplier_rows(
    V, rows: CellTable, cells: np.ndarray, ref: Reference, multiplier, sign, lmbda_clip, bubble
) -> np.ndarray:
    """Set λ_h clipped and the Bernstein bubble of :func:`multiplier_functions` on the owned
    ``cells`` (``rows``: their rows of the table; no scatter) and return their κ."""
    nodal = clipped(rows.lam, sign)
    dofs = V.dofmap.list[cells]
    lmbda_clip.x.array[dofs] = nodal
    kappa = np.ones(len(rows))
    if multiplier is not None:
        kappa[:] = 0.0 if multiplier == "facets" else 1.0
        entities = (
            [(cell_rule(ref), np.arange(len(rows)))]
            if multiplier == "cells"
            else [
                (facet_rule(ref, j), np.flatnonzero(rows.kind[:, j] == CONTACT))
                for j in range(ref.d + 1)
            ]
        )
        for rule, where in entities:
            if not rule.edges and P1_SHORTCUT:  # P1: κ = 1 and no bubble (shares' rule)
                continue
            _, k, beta = shares(nodal[where], rule, sign)
            kappa[where] = np.maximum(kappa[where], k) if multiplier == "facets" else k
            for e, (_, _, mid) in enumerate(rule.edges):
                bubble.x.array[dofs[where, mid]] = beta[:, e]
        kappa[kappa == 0.0] = 1.0
    return kappa


def oscillation(table: CellTable, ref: Reference) -> np.ndarray:
    """osc_T of :class:`Flux` for the table's cells.

    The trace inequality: for v ∈ H¹(T), F a facet and x_F the opposite vertex, the field
    x − x_F has normal component d|T|/|F| on F and 0 on the other facets and divergence d,
    so (d|T|/|F|)‖v‖²_F = ∫_T d v² + 2v ∇v·(x − x_F) ≤ d‖v‖²_T + 2h_T‖v‖_T‖∇v‖_T; with v − v̄_T
    (‖v − v̄_T‖_T ≤ h_T/π ‖∇v‖_T) and t − Π_p t ⊥ constants on F this gives C_{T,F}."""
    absdet, h, size, C = _measures(table.x, ref.d)
    Q, w = ref.Q, ref.w
    rest = table.f - (table.f @ (w[:, None] * Q.T)) @ Q  # f − Π_p f at the points
    osc = h / np.pi * np.sqrt(np.maximum(absdet * (rest**2 @ w), 0.0))
    q, wS = ref.q, ref.wS
    trest = table.t - (table.t @ (wS[:, None] * q.T)) @ q  # t − Π_p t, (n, D, nqf)
    for j in range(ref.d + 1):
        osc += C[:, j] * np.sqrt(size[:, j] * (trest[:, j] ** 2 @ wS))
    return osc / np.sqrt(table.k.min(axis=1))


def _measures(x: np.ndarray, d: int) -> tuple[np.ndarray, ...]:
    """|det J|, h_T, |F_j| / |F̂| and the trace constants C_{T,F_j} of :class:`Flux` of the
    cells with vertices ``x`` (n, d + 1, d)."""
    from .operators import det_inv

    D = d + 1
    J = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
    absdet = np.abs(det_inv(J)[0])
    vol = absdet / np.prod(np.arange(1, d + 1))
    h = np.max(
        [np.linalg.norm(x[:, i] - x[:, j], axis=1) for i in range(D) for j in range(i)], axis=0
    )
    size = np.empty((len(x), D))
    for j in range(D):
        E = x[:, [v for v in range(D) if v != j]]
        E = E[:, 1:] - E[:, :1]
        size[:, j] = np.sqrt(np.abs(np.linalg.det(np.einsum("nad,nbd->nab", E, E))))
    area = size / np.prod(np.arange(1, d))
    C = h[:, None] * np.sqrt(area / vol[:, None] * (1 / np.pi**2 + 2 / (d * np.pi)))
    return absdet, h, size, C


def _multiplier_oscillation(
    table: CellTable, ref: Reference, multiplier: str | None, sign: float
) -> np.ndarray:
    """The part of osc_T the multiplier adds when the flux is of lower degree than λ_h (the
    lowest-order flux of a P1 solution carries Π_p λ̃_h, not λ̃_h itself):

        k_T,min^{-1/2} h_T/π ‖λ̃_h − Π_p λ̃_h‖_T                  (obstacle),
        k_T,min^{-1/2} Σ_{F ⊂ ∂T ∩ Γ_C} C_{T,F} ‖λ̃_h − Π_p λ̃_h‖_F   (Signorini),

    bounds ⟨λ̃_h − Π_p λ̃_h, v⟩ by ‖k^{1/2}∇v‖_T as the data oscillation does (:func:`oscillation`:
    the rest is orthogonal to constants); zero when p is the degree of λ_h."""
    osc = np.zeros(len(table))
    if multiplier is None or not ref.lowest:
        return osc
    nodal = clipped(table.lam, sign)
    if multiplier == "cells":
        absdet, h, _, _ = _measures(table.x, ref.d)
        entities = [(cell_rule(ref), np.arange(len(table)), h / np.pi, absdet)]
    else:  # the cells with a contact facet only
        crow = np.flatnonzero(np.any(table.kind == CONTACT, axis=1))
        _, _, size, C = _measures(table.x[crow], ref.d)
        entities = []
        for j in range(ref.d + 1):
            on = np.flatnonzero(table.kind[crow, j] == CONTACT)
            entities.append((facet_rule(ref, j), crow[on], C[on, j], size[on, j]))
    for rule, rows, factor, measure in entities:
        kappa = shares(nodal[rows], rule, sign)[1]  # P1: λ̃ = κ λ_h on the entity, no bubble
        lt = kappa[:, None] * (nodal[rows] @ rule.phi.T)
        rest = lt - (lt @ (rule.w[:, None] * rule.basis.T)) @ rule.basis
        osc[rows] += factor * np.sqrt(np.maximum(measure * (rest**2 @ rule.w), 0.0))
    return osc / np.sqrt(table.k.min(axis=1))
