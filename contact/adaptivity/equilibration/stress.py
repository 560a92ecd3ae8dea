"""An equilibrated stress for linear elasticity: row-wise Raviart–Thomas with weak symmetry on
vertex patches (docs/theory.md §9.2), the elastic counterpart of :mod:`.flux`.

Given u_h ∈ P_p^d (plane strain in 2D), the load f, the tractions t on Γ_N and the contact
traction the solve produced on Γ_C (the normal pressure λ_h along the obstacle's normal n,
and with friction the tangential traction λ_t,h), it returns σ_h whose rows σ_h,r lie in
RT_{p+1} (:data:`EXTRA`), with, exactly up to round-off,

    −div σ_h = Π_{p+1} f    in every cell,
    σ_h ν = Π_{p+1} t  on Γ_N,    σ_h ν = λ̃_h n + λ̃_t   on Γ_C,    (σ_h ν)_k = 0 for each
    component k that is neither prescribed (Γ_D, a symmetry plane x_k = const) nor loaded,
    ∫_T as(σ_h) = 0 on every cell T       (weak symmetry, as σ = σ_ij − σ_ji),

λ̃_h, λ̃_t the discrete multipliers as :mod:`.multiplier` carries them (σλ̃_h ≤ 0 pointwise;
shared among a facet's vertices with the solve's own lumping, so each patch balances).

**Patch problems** (Ern & Vohralík, SINUM 53, 2015, row by row; weak symmetry against
piecewise constants as in Arnold–Falk–Winther's lowest-order element, cf. Riedlbeck, Di
Pietro, Ern, Granet & Kazymyrenko, Comput. Math. Appl. 73, 2017, and Bertrand, Kober,
Moldenhauer & Starke, NMPDE 37, 2021).  For a vertex a with hat ψ_a and patch ω_a,

    σ_a = argmin ‖C^{-1/2}(σ − ψ_a σ(u_h))‖²_{ω_a} + κ ‖skw σ‖²_{ω_a}   over σ with rows in
    RT_{p+1}(ω_a),  −div σ = Π(ψ_a f − σ(u_h)∇ψ_a) in each cell,  σν = Π(ψ_a t) on Γ_N, the
    share of vertex a of λ̃_h n + λ̃_t on Γ_C, σν = 0 on the rest of ∂ω_a (row r free on a
    facet where component r is prescribed),  ∫_T as σ = m_{a,T} on each cell T ⊂ ω_a,

and σ_h = Σ_a σ_a.  A closed patch (no free facet) must carry ∫_{ω_a} as σ_a = R_a, its
rotational balance: for any admissible σ, ∫_{ω_a} σ : W = −∫ div σ·W(x − x_a) + ∫_{∂ω_a} σν·
W(x − x_a) (∇(W(x − x_a)) = W, W skew); R_a is the residual of the discrete equation
against ψ_a W(x − x_a), not zero for P_1.  :mod:`.rotations` splits each R_a over the
patch's cells so that every cell's as-moments add up to zero over its vertices: the
weak symmetry holds on every cell.  The penalty κ (``skew_weight``) then reduces what
remains of skw σ_h inside the cells.  Why the pieces: without the split, 99 % of ‖as σ_h‖
was cell means (hertz_2d, the Tresca scene); with RT_p rows, or without κ, the remaining
asymmetry stalls the effectivity near 1.6–1.8 on the Tresca scene; weak symmetry against
P_1 per cell over-constrains the patches (inconsistent systems: a defect of 1e-2).

The cells of a patch meet only through the Lagrange multipliers μ of the normal moments,
one block per (facet through a, row) that is not free; per cell, with σ_r = R̂β_r + Zγ_r
(β fixed by the divergence, :mod:`.reference`), the mass M of the objective (rows
coupled through the compliance's trace and the penalty), the as-constraint a_Z γ = c and
H = M_Z⁻¹,

    γ = P (q − Oᵀμ) + H a_Zᵀ G⁻¹ c,   P = H − H a_Zᵀ G⁻¹ a_Z H,   G = a_Z H a_Zᵀ,

so that O σ = h − S μ with S = O P Oᵀ, as in :mod:`.operators` with P for M_Z⁻¹.  A
closed patch has the rigid motions (d(d+1)/2) in the kernel of its μ-system and a
consistent right-hand side up to the algebraic residual of the solve; they do not change
σ_a.  The residual the solves leave is reported as ``defect``.

**Cost.**  The patches are taken in blocks of :data:`PATCHES` vertices: the operators of
the block's cells (S, P Oᵀ and σ_a's cell problem at μ = 0 per vertex) are computed, the
block's μ-systems solved and σ_a added, then the cell arrays dropped (for the whole mesh
they would be 810 doubles per cell with P1; writing them the first time cost more than
computing them).  ``backend="compiled"`` (the default) computes the cell operators and
solves the patches in C (:mod:`.stress_c`), ``"numpy"`` with batched NumPy (the
reference: the patches of one size in one call); no Python loop runs over vertices or
cells.  Measured on hertz_2d (``bench_equilibrated.py --cost-elastic``): RESULTS §12.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field, replace

import basix
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from . import rotations, stress_c
from .cells import (
    CONTACT,
    DIRICHLET,
    FLUX,
    CellTable,
    FluxData,
    complete,
    local_table,
    return_to_owners,
)
from .flux import multiplier_functions, oscillation, rt_function
from .multiplier import clipped, entity_rule, shares
from .operators import CellOperators, det_inv, projected_mass
from .patches import assemble_patches, spoke_keys
from .reference import CELLS, Reference, reference

__all__ = ["BACKENDS", "Stress", "StressData", "reconstruct_stress", "skew_pairs"]

#: the patch stage: "compiled" (the C kernel of :mod:`.stress_c`) or "numpy" (the reference,
#: :func:`_multipliers`; batched over the patches of one size)
BACKENDS = ("compiled", "numpy")


def skew_pairs(d: int) -> list[tuple[int, int]]:
    """The components (i, j) of as σ = σ_ij − σ_ji: one in 2D, three in 3D."""
    return [(0, 1)] if d == 2 else [(1, 2), (2, 0), (0, 1)]


@dataclass
class StressData:
    """What the stress reconstruction is given (DOLFINx objects, UFL and numbers).

    ``dirichlet[r]``: the facet tags where component r is prescribed (Γ_D and the symmetry
    planes normal to e_r); ``neumann``: tag → the traction t (a UFL vector); ``contact``:
    the Γ_C tags, where the traction is λ_h n (+ λ_t with friction); ``normal``: the
    obstacle's unit normal n (constant: a plane); ``lmbda_h``: the normal pressure (a
    scalar Lagrange function, ≤ 0); ``lmbda_t``: the tangential traction (a vector Lagrange
    function, or None).  Exterior facets no tag names carry σν = 0."""

    u_h: fem.Function
    f: ufl.core.expr.Expr
    mu: float
    lmbda_L: float
    facet_tags: dmesh.MeshTags
    dirichlet: tuple[tuple[int, ...], ...]
    neumann: dict = field(default_factory=dict)
    contact: tuple[int, ...] = ()
    normal: np.ndarray | None = None
    lmbda_h: fem.Function | None = None
    lmbda_t: fem.Function | None = None
    skew_weight: float = 0.0


@dataclass
class Stress:
    """σ_h as d RT_p rows (:attr:`rows`) and as a UFL matrix (:attr:`sigma`), the multipliers
    it carries on Γ_C (λ̃_h as UFL, :attr:`lmbda`), osc_T of each owned cell (the vector
    version of :class:`.flux.Flux`'s: (Σ_r osc_T,r²)^{1/2} with k = 1), the residual the
    least-squares patch solves left (:attr:`defect`, force units) and timings (seconds)."""

    rows: list[fem.Function]
    lmbda: ufl.core.expr.Expr | None
    osc: np.ndarray
    defect: float
    seconds: dict = field(default_factory=dict)

    @property
    def sigma(self):
        return ufl.as_matrix([[row[j] for j in range(len(self.rows))] for row in self.rows])


#: the rows of σ_h lie in RT_{p+EXTRA} for u_h ∈ P_p.  With RT_p the asymmetry that the
#: weak symmetry leaves inside the cells is larger: the Tresca scene's effectivity on levels
#: 3–7 (P1, κ = 4 C_K²/(2μ), before the Dirichlet lifting of :mod:`.elastic`) was 1.72–1.87
#: with RT_1 rows and 1.43–1.54 with RT_2 (docs/theory.md §9.2)
EXTRA = 1


@functools.cache
def _rule(d: int, p_u: int, p_s: int, j: int):
    """The contact-facet rule (:mod:`.multiplier`) of facet j: λ_h's Lagrange basis of degree
    p_u (the solve's lumping), the points and test polynomials of RT_{p_s}'s reference."""
    r = reference(d, p_s)
    return entity_rule(d, p_u, r.XF[j], r.wS, r.q, np.array([v for v in range(d + 1) if v != j]))


@functools.cache
def _data(d: int, p_u: int, p_s: int) -> dict:
    """Reference tables of the data terms: the gradients of u_h's Lagrange basis (degree
    p_u) at RT_{p_s}'s cell points, and the weighted hats times the divergence tests."""
    r = reference(d, p_s)
    lag = basix.create_element(
        basix.ElementFamily.P, CELLS[d], p_u, basix.LagrangeVariant.gll_warped
    )
    return {
        "dphi_u": np.moveaxis(np.asarray(lag.tabulate(1, r.X))[1:, :, :, 0], 0, -1),  # (nq, nu, d)
        "wlamQ": np.einsum("q,qa,jq->qaj", r.w, r.lam, r.Q),
        "wQ": np.einsum("q,jq->qj", r.w, r.Q),
    }


def reconstruct_stress(data: StressData, backend: str = "compiled") -> Stress:
    """σ_h of the module docstring (collective).  ``backend``: the patch stage, one of
    :data:`BACKENDS` (the same σ_h to round-off)."""
    if backend not in BACKENDS:
        raise ValueError(f"backend: expected one of {BACKENDS}, got {backend!r}")
    t0 = time.perf_counter()
    u_h = data.u_h
    V = u_h.function_space
    msh = V.mesh
    d = msh.topology.dim
    p = V.element.basix_element.degree
    ref = reference(d, p + EXTRA)
    comm = msh.comm
    tables, lam_t, n_owned = _row_tables(data, ref)
    source = np.full(n_owned, comm.rank)
    work = [complete(comm, t, source)[0] for t in tables]  # this rank's rows first
    # None for NumPy, also where the kernel cannot be had (no C compiler, say): the same
    # numbers, slower (compiled.load has warned once)
    kernel = stress_c.library(comm, ref) if backend == "compiled" else None
    seconds = {"tables": time.perf_counter() - t0}
    t0 = time.perf_counter()
    # the as-moments of every (owned cell, vertex): each patch's balance spread over its cells
    div = _Divergence(work, ref, p, data.mu, data.lmbda_L)
    bdata = _boundary_data(tables, lam_t, ref, p, data.normal)
    free = np.unique(
        np.concatenate(
            [
                data.facet_tags.indices[np.isin(data.facet_tags.values, ids)]
                for ids in data.dirichlet
            ]
        )
    ).astype(np.int32)
    area = div.geometry["absdet"][:n_owned] / np.prod(np.arange(1, d + 1))
    moments = _rotation_moments(tables[0], ref, div.beta[:n_owned], bdata)
    m = rotations.spread(msh, free, area, moments)
    seconds["rotations"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    # the as-moments and the tangential traction's coefficients ride along to the patches'
    # ranks in the U column of a copy of the first table
    extra = replace(tables[0], U=np.concatenate([m.reshape(n_owned, -1), *lam_t], axis=1))
    extra_w, src = complete(comm, extra, source)
    nm = m.shape[1] * m.shape[2]
    nu = lam_t[0].shape[1] if lam_t else 0
    m_w = extra_w.U[:, :nm].reshape(-1, *m.shape[1:])
    lam_t_w = [extra_w.U[:, nm + k * nu : nm + (k + 1) * nu] for k in range(len(lam_t))]
    seconds["gather"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    vmap = msh.topology.index_map(0)
    owned = np.arange(*vmap.local_range, dtype=np.int64)
    alpha, defect, code = _solve(work, div, lam_t_w, m_w, owned, ref, data, kernel)
    code = comm.allreduce(code, op=MPI.MAX)
    if code:
        what = {1: "a singular cell block", 2: "a singular patch system", 3: "out of memory"}
        raise RuntimeError(f"stress reconstruction: {what.get(code, f'error {code}')}")
    seconds["patches"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    offset = msh.topology.index_map(d).local_range[0]
    rows = []
    for r in range(d):
        a_r = return_to_owners(comm, work[0].gcell, src, alpha[:, r], n_owned, offset)
        row = rt_function(msh, ref, np.ascontiguousarray(a_r))
        row.name = f"sigma_h_{r}"
        rows.append(row)
    osc = np.sqrt(sum(oscillation(t, ref) ** 2 for t in tables))
    lmbda = None
    if data.lmbda_h is not None and data.contact:
        S = data.lmbda_h.function_space
        DG0 = fem.functionspace(msh, ("DG", 0))
        ref_u = reference(d, p)
        clip, bubble, kappa = multiplier_functions(S, tables[0], ref_u, "facets", -1.0, DG0)
        lmbda = kappa * (clip - 0.5 * bubble)
    seconds["assemble"] = time.perf_counter() - t0
    return Stress(rows, lmbda, osc, comm.allreduce(defect), seconds)


def _row_tables(data: StressData, ref: Reference) -> tuple[list[CellTable], list[np.ndarray], int]:
    """One cell table per row r (:mod:`.cells`): component r of u_h, f_r, k = 1, the facet
    kinds of component r, t_r on Γ_N, λ_h (the normal pressure) in ``lam``; and with friction
    the nodal coefficients of each component of the tangential traction (n, nu)."""
    V = data.u_h.function_space
    d = V.mesh.topology.dim
    tables, lam_t, n_owned = [], [], 0
    for r in range(d):
        Vr, _ = V.sub(r).collapse()
        u_r = fem.Function(Vr)
        u_r.interpolate(data.u_h.sub(r))
        zero = fem.Constant(V.mesh, 0.0)  # + 0: a component UFL simplified to Zero stays
        flux = FluxData(  # tied to the mesh
            u_r,
            data.f[r] + zero,
            fem.Constant(V.mesh, 1.0),
            data.facet_tags,
            dirichlet=data.dirichlet[r],
            neumann={tag: t[r] + zero for tag, t in data.neumann.items()},
            contact={tag: fem.Constant(V.mesh, 0.0) for tag in data.contact},
            lmbda_h=data.lmbda_h,
        )
        table, n_owned = local_table(flux, ref)
        tables.append(table)
        if data.lmbda_t is not None:
            lt = fem.Function(Vr)
            lt.interpolate(data.lmbda_t.sub(r))
            lam_t.append(lt.x.array[Vr.dofmap.list[:n_owned]])
    return tables, lam_t, n_owned


# ---------------------------------------------------------------------------------------
# the cell operators of the coupled rows
# ---------------------------------------------------------------------------------------
@dataclass
class _Cells:
    """Per cell of the work rows (module docstring), what the patches read: S (n, D·d·nf,
    D·d·nf), and per vertex a of the cell σ_a's cell problem at μ = 0 — γ⁰ = P q + H a_Zᵀ
    G⁻¹ c with c = m_{a,T} − a_R β its as-constraint's right-hand side, the normal moments
    h of Rβ + Zγ⁰ and the prescribed data in the global facet basis — and P Oᵀ."""

    S: np.ndarray  # (n, D d nf, D d nf)
    gamma0: np.ndarray  # (n, D, d mz)
    h: np.ndarray  # (n, D, D d nf), rows (facet, row, k)
    data: np.ndarray  # (n, D, D d nf)
    POt: np.ndarray  # (n, d mz, D d nf): P Oᵀ


def _block_diag(X: np.ndarray, d: int, D: int, nf: int) -> np.ndarray:
    """(n, D nf, k) per-row normal moments → (n, D d nf, d k), rows (facet, row, moment)."""
    n, _, k = X.shape
    out = np.zeros((n, D, d, nf, d, k))
    Xr = X.reshape(n, D, nf, k)
    for r in range(d):
        out[:, :, r, :, r, :] = Xr
    return out.reshape(n, D * d * nf, d * k)


def _objective(T: np.ndarray, mu: float, lam: float, skew_weight: float) -> np.ndarray:
    """The mass of the patch objective ∫ C⁻¹σ:τ + κ ∫ skw σ : skw τ, C⁻¹σ = (σ − c tr σ I)/(2μ),
    c = λ/(2μ + dλ), from the row blocks T (n, d, d, a, b) of ∫ (φ·e_r)(φ·e_s): (n, d a, d b),
    M_rs = Σ_tu W[r, s, t, u] T_tu with the constant weights W of :func:`_weights`."""
    n, d, _, a, b = T.shape
    W = _weights(d, mu, lam, skew_weight).reshape(d * d, d * d)
    M = (W @ T.reshape(n, d * d, a * b)).reshape(n, d, d, a, b)
    return np.ascontiguousarray(M.transpose(0, 1, 3, 2, 4)).reshape(n, d * a, d * b)


@functools.cache
def _weights(d: int, mu: float, lam: float, skew_weight: float) -> np.ndarray:
    """W[r, s, t, u]: the weight of T_tu in the block (r, s) of :func:`_objective`."""
    c_lam = lam / (2.0 * mu + d * lam)
    W = np.zeros((d, d, d, d))
    for r in range(d):
        for s in range(d):
            W[r, s, r, s] -= c_lam / (2.0 * mu)
            if r == s:
                for t in range(d):
                    W[r, s, t, t] += 1.0 / (2.0 * mu)
    for i, j in skew_pairs(d):  # + κ ∫ skw σ : skw τ = κ/2 ∫ (σ_ij − σ_ji)(τ_ij − τ_ji)
        W[i, i, j, j] += 0.5 * skew_weight
        W[j, j, i, i] += 0.5 * skew_weight
        W[i, j, j, i] -= 0.5 * skew_weight
        W[j, i, i, j] -= 0.5 * skew_weight
    return W


#: vertex patches solved per block (:func:`_solve`): the cell operators of a block's cells
#: are computed, used and dropped (a cell that touches two blocks' vertices is computed in
#: both), so the per-cell arrays (810 doubles per cell for P1) never exist for the whole
#: mesh (hertz_2d, 125k cells: the first touch of their memory cost more than the work)
PATCHES = 2048


def _cell_operators(
    table: CellTable,
    rows: np.ndarray,
    div: _Divergence,
    bdata: np.ndarray,
    m_as: np.ndarray,
    ref: Reference,
    data: StressData,
    kernel,
) -> tuple[_Cells, int]:
    """The :class:`_Cells` of the rows ``rows`` of ``table`` (``div``: the table's
    divergence data, ``bdata``: its prescribed moments of :func:`_boundary_data`,
    ``m_as``: its as-moments), in C (``kernel``: :mod:`.stress_c`'s library) or NumPy
    (None), and the kernel's error code."""
    d, D, nf, m = ref.d, ref.d + 1, ref.nf, ref.m
    n, DB, dmz = len(rows), D * d * nf, d * ref.Z.shape[1]
    out = _Cells(
        np.empty((n, DB, DB)), np.empty((n, D, dmz)), np.empty((n, D, DB)),
        np.empty((n, D, DB)), np.empty((n, dmz, DB)),
    )  # fmt: skip
    bdata, m_as = bdata[rows], m_as[rows]
    mu, lam, skew_weight = float(data.mu), float(data.lmbda_L), float(data.skew_weight)
    ops = CellOperators(table, rows, ref)
    n = len(ops.rows)
    g = ops.geometry
    J = div.geometry["J"][rows]
    Zb = np.kron(np.eye(d), ref.Z)  # (d m, d mz)
    Rb = np.kron(np.eye(d), ref.R)  # (d m, d np)
    # ∫_T σ_ij − σ_ji: ∫_T (φ·e_c) = s (J M1)_c with M1[k, l] = ∫̂ φ̂_l,k
    M1 = np.einsum("q,qlk->kl", ref.w, ref.phi)
    # σ_a's cell problem at μ = 0, per vertex a: the load g_a = ∫_T ψ_a ε(u_h) : φ =
    # s Σ_q w ψ_a (Jᵀ ε_r)·φ̂ (C⁻¹ σ(u_h) = ε(u_h)), q = Z_bᵀ g_a − Z_bᵀ M R_b β
    nq, mz = len(ref.w), ref.Z.shape[1]
    ref_eps = np.matmul(div.eps[rows].reshape(n, nq * d, d), J)  # (n, nq·r, i): Jᵀ ε_r
    ref_eps = ref_eps.reshape(n, nq, d, d).transpose(0, 2, 1, 3).reshape(n, d, nq * d)
    q0 = (ref_eps @ _load_table(d, ref.p)).reshape(n, d, D, mz).transpose(0, 2, 1, 3)
    q0 = g["s"][:, None, None] * q0.reshape(n, D, d * mz)  # Z_bᵀ g_a
    bflat = div.beta[rows].reshape(n, D, -1)
    Pm = ref.P[ops.perm]  # (n, D, nf, nf): the data in the global facet basis
    glob = np.matmul(bdata.reshape(n, D, D * d, nf), Pm)  # (n, facet j, (a, r), l)
    out.data[:] = glob.reshape(n, D, D, d, nf).transpose(0, 2, 1, 3, 4).reshape(n, D, -1)
    if kernel is not None:
        arrays = {
            "J": J,
            "s": g["s"],
            "absdet": g["absdet"],
            "ZZ": projected_mass(ref, "ZZ"),
            "ZR": projected_mass(ref, "ZR"),
            "W": _weights(d, mu, lam, skew_weight),
            "M1Z": M1 @ ref.Z,
            "M1R": M1 @ ref.R,
            "OZ": ops.OZ,
            "OR": ops.OR,
            "q0": q0,
            "beta": bflat,
            "m": m_as,
        }
        return out, stress_c.cell_operators(kernel, ref, arrays, vars(out))
    # the objective's mass M (rows r, s) only enters projected: M_Z = Z_bᵀ M Z_b and
    # Z_bᵀ M R_b, each a combination of T_rs = ∫_T (φ·e_r)(φ·e_s) of the Piola-mapped basis,
    # Σ_ij J_ri J_sj mass_ij / |det J|, projected on the reference (Zᵀ mass_ij Z, Zᵀ mass_ij R)
    JJ = np.einsum("nri,nsj->nrsij", J, J) / g["absdet"][:, None, None, None, None]
    blocks = {
        right: np.einsum("nrsij,ijab->nrsab", JJ, projected_mass(ref, right), optimize=True)
        for right in ("ZZ", "ZR")
    }
    H = np.linalg.inv(_objective(blocks["ZZ"], mu, lam, skew_weight))
    ZMR = _objective(blocks["ZR"], mu, lam, skew_weight)
    JM1 = g["s"][:, None, None] * np.einsum("nck,kl->ncl", J, M1)  # (n, d, m)
    pairs = skew_pairs(d)
    A4 = np.zeros((n, len(pairs), d, m))
    for k, (i, j) in enumerate(pairs):
        A4[:, k, i] += JM1[:, j]
        A4[:, k, j] -= JM1[:, i]
    A = A4.reshape(n, len(pairs), d * m)
    aZ, aR = A @ Zb, A @ Rb
    HaT = H @ np.transpose(aZ, (0, 2, 1))
    HaG = HaT @ np.linalg.inv(aZ @ HaT)
    P = H - HaG @ np.transpose(HaT, (0, 2, 1))
    OZ = _block_diag(ops.OZ, d, D, nf)
    OR = _block_diag(ops.OR, d, D, nf)
    out.POt[:] = P @ np.transpose(OZ, (0, 2, 1))
    out.S[:] = OZ @ out.POt
    q = q0 - np.einsum("nzb,nab->naz", ZMR, bflat)
    Pq = np.einsum("nyz,naz->nay", P, q)
    c = m_as - np.einsum("nkb,nab->nak", aR, bflat)
    out.h[:] = np.einsum("nfb,nab->naf", OR, bflat) + np.einsum("nfz,naz->naf", OZ, Pq)
    out.h[:] += np.einsum("nfk,nak->naf", OZ @ HaG, c)
    out.gamma0[:] = Pq + np.einsum("nzk,nak->naz", HaG, c)
    return out, 0


@functools.cache
def _load_table(d: int, p: int) -> np.ndarray:
    """T[(q, i), (a, z)] = w_q ψ_a(q) Σ_l φ̂_l,i(q) Z_lz of RT_p's reference (d, p): the load
    Z_bᵀ g_a of σ_a's cell problem is s (Jᵀ ε_r)(q)_i T per row r."""
    r = reference(d, p)
    T = np.einsum("q,qa,qli,lz->qiaz", r.w, r.lam, r.phi, r.Z)
    return T.reshape(len(r.w) * d, -1)


@dataclass
class _Divergence:
    """The cell data every patch of a cell shares: the geometry, ε(u_h) at the points and
    the divergence moments β (n, d+1 vertices, d rows, np) of each vertex's share,
    B̂ α = β = −s ∫_T Π_p(ψ_a f_r − σ_r(u_h)·∇ψ_a) Q_j."""

    beta: np.ndarray
    eps: np.ndarray  # (n, nq, d, d)
    geometry: dict  # J, s, absdet

    def __init__(self, tables: list[CellTable], ref: Reference, p_u: int, mu, lam) -> None:
        d = ref.d
        x = tables[0].x
        J = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
        det, Jinv = det_inv(J)
        t = _data(d, p_u, ref.p)
        grad = np.stack(
            [np.einsum("nu,qud,ndi->nqi", tb.U, t["dphi_u"], Jinv, optimize=True) for tb in tables],
            axis=2,
        )  # (n, nq, r, i) = ∂u_r/∂x_i
        self.eps = 0.5 * (grad + np.swapaxes(grad, 2, 3))
        tr = np.einsum("nqii->nq", self.eps)
        sig = 2.0 * mu * self.eps + lam * tr[:, :, None, None] * np.eye(d)
        absdet = np.abs(det)
        grad_psi = np.einsum("nki,ak->nai", Jinv, ref.dlam)  # (n, D, d) physical ∇ψ_a
        # Σ_q w_q σ_ri Q_j first (the points contracted before ∇ψ_a: no (n, nq, D, d) array)
        sigQ = np.tensordot(sig, t["wQ"], axes=([1], [0]))  # (n, r, i, j)
        R0 = np.stack(
            [
                np.einsum("nq,qaj->naj", tb.f, t["wlamQ"])
                - np.einsum("nij,nai->naj", sigQ[:, r], grad_psi)
                for r, tb in enumerate(tables)
            ],
            axis=2,
        )  # (n, D, d, np) per reference measure
        self.beta = -(np.sign(det) * absdet)[:, None, None, None] * R0
        self.geometry = {"J": J, "s": np.sign(det), "absdet": absdet}


def _boundary_data(
    tables: list[CellTable], lam_t: list[np.ndarray], ref: Reference, p_u: int, normal
) -> np.ndarray:
    """The prescribed outward-flux moments of each vertex's share, per row, in the facet's
    local basis: (n, D facets, D vertices, d rows, nf), per physical measure; zero on the
    facets a row does not prescribe.  On Γ_C: n_r λ̃_h + λ̃_t,r (``lam_t``: the tangential
    traction's nodal coefficients per row, or empty)."""
    d, D = ref.d, ref.d + 1
    n = len(tables[0])
    x = tables[0].x
    size = np.empty((n, D))
    for j in range(D):
        E = x[:, [v for v in range(D) if v != j]]
        E = E[:, 1:] - E[:, :1]
        size[:, j] = np.sqrt(np.abs(np.linalg.det(np.einsum("nad,nbd->nab", E, E))))
    base = np.einsum("q,jqa,kq->jakq", ref.wS, ref.lamF, ref.q)
    out = np.zeros((n, D, D, d, ref.nf))
    normal = np.zeros(d) if normal is None else np.asarray(normal, dtype=float)
    for r, t in enumerate(tables):
        prescribed = (t.kind == FLUX) | (t.kind == CONTACT)
        out[:, :, :, r] = np.einsum(
            "nj,jakq,njq->njak", size * prescribed, base, t.t, optimize=True
        )
        for j in range(D):
            on = np.flatnonzero(t.kind[:, j] == CONTACT)
            if not len(on):
                continue
            rule = _rule(d, p_u, ref.p, j)
            mom = normal[r] * shares(clipped(t.lam[on], -1.0), rule, -1.0)[0]
            if lam_t:  # the tangential traction's component r (no sign)
                mom = mom + shares(lam_t[r][on], rule, 0.0)[0]
            out[on, j, :, r] += size[on, j][:, None, None] * mom
    return out


def _rotation_moments(table: CellTable, ref: Reference, beta: np.ndarray, bdata: np.ndarray):
    """m_{a,T} of the module docstring for each cell and vertex: (n, D, nas).  ``beta``:
    (n, D, d, np) the reference divergence moments of σ_a (B̂ α = β); ``bdata``: the
    prescribed moments of :func:`_boundary_data`."""
    d, D = ref.d, ref.d + 1
    x = table.x
    n = len(x)
    J = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
    s = np.sign(np.linalg.det(J))
    # x − x_a is affine on the reference: its moments against Q̂_j (cells) and q̂_k (facets)
    # are (x_0 − x_a) ∫̂ Q̂_j + J ∫̂ Q̂_j X̂, from the reference tables
    m0, m1 = ref.Q @ ref.w, np.einsum("q,jq,ql->jl", ref.w, ref.Q, ref.X)
    f0, f1 = ref.q @ ref.wS, np.einsum("q,kq,fql->fkl", ref.wS, ref.q, ref.XF)
    Jm1 = np.einsum("ncl,jl->njc", J, m1)  # (n, np, d)
    Jf1 = np.einsum("ncl,fkl->nfkc", J, f1)  # (n, D, nf, d)
    out = np.zeros((n, D, len(skew_pairs(d))))
    for a in range(D):
        x0a = x[:, 0] - x[:, a]  # (n, d)
        rel = x0a[:, None, :] * m0[None, :, None] + Jm1  # ∫̂ Q̂_j (x − x_a): (n, np, d)
        frel = x0a[:, None, None, :] * f0[None, None, :, None] + Jf1  # (n, D, nf, d)
        for k, (i, j) in enumerate(skew_pairs(d)):
            # W(x − x_a): w_i = (x − x_a)_j, w_j = −(x − x_a)_i
            cw = np.einsum("nj,nj->n", beta[:, a, i], rel[..., j]) - np.einsum(
                "nj,nj->n", beta[:, a, j], rel[..., i]
            )
            out[:, a, k] = -s * cw
            out[:, a, k] += np.einsum("nfk,nfk->n", bdata[:, :, a, i], frel[..., j])
            out[:, a, k] -= np.einsum("nfk,nfk->n", bdata[:, :, a, j], frel[..., i])
    return out


# ---------------------------------------------------------------------------------------
# the patches
# ---------------------------------------------------------------------------------------
def _solve(
    tables: list[CellTable],
    div: _Divergence,
    lam_t: list[np.ndarray],
    m_as: np.ndarray,
    owned: np.ndarray,
    ref: Reference,
    data: StressData,
    kernel,
):
    """α (n, d, m): Σ_a σ_a|_T over the owned vertices a (``m_as``: the as-moments of each
    (cell, vertex), :mod:`.rotations`; ``div``: the divergence data of the rows), the summed
    defect and the compiled kernel's error code (``kernel``: None for NumPy)."""
    d, m = ref.d, ref.m
    n = len(tables[0])
    p_u = data.u_h.function_space.element.basix_element.degree
    bdata = _boundary_data(tables, lam_t, ref, p_u, data.normal)
    kinds = np.stack([tb.kind for tb in tables], axis=2)  # (n, D facets, d rows)
    alpha = np.zeros((n, d, m))
    pairs = _pairs(tables[0], owned, ref, kinds)
    defect, err = 0.0, 0
    for p0 in range(0, len(pairs.size), PATCHES):  # blocks of whole patches
        p1 = min(p0 + PATCHES, len(pairs.size))
        sel = slice(pairs.pstart[p0], pairs.pstart[p1])
        rows, local = np.unique(pairs.prow[sel], return_inverse=True)
        cells, code = _cell_operators(tables[0], rows, div, bdata, m_as, ref, data, kernel)
        block = _Pairs(
            local,
            pairs.ploc[sel],
            pairs.patch[sel] - p0,
            pairs.pstart[p0 : p1 + 1] - pairs.pstart[p0],
            pairs.size[p0:p1],
            pairs.loc[sel],
        )
        got, code2 = _patches(block, ref, cells, div.beta[pairs.prow[sel], pairs.ploc[sel]],
                              rows, alpha, kernel)  # fmt: skip
        defect += got
        err = max(err, code, code2)
    return alpha, defect, err


@dataclass
class _Pairs:
    """The pairs (cell row, local vertex a) of the patches, sorted by patch: ``prow``,
    ``ploc``, the patch of each (``patch``; ``pstart``: the offsets of each patch's pairs),
    the unknown (spoke, row) slots of each patch (``size``) and the patch-local slot of
    each of a pair's (spoke, row) (``loc`` (npair, d·d), −1 where the row is prescribed)."""

    prow: np.ndarray
    ploc: np.ndarray
    patch: np.ndarray
    pstart: np.ndarray
    size: np.ndarray
    loc: np.ndarray


def _pairs(table: CellTable, owned: np.ndarray, ref: Reference, kinds: np.ndarray) -> _Pairs:
    """The :class:`_Pairs` of the vertices ``owned`` (``kinds``: (n, D facets, d rows))."""
    d, D = ref.d, ref.d + 1
    prow, ploc = np.nonzero(np.isin(table.gvert, owned))
    verts = table.gvert[prow, ploc]
    order = np.argsort(verts, kind="stable")
    prow, ploc, verts = prow[order], ploc[order], verts[order]
    uniq, patch = np.unique(verts, return_inverse=True)
    npair = len(prow)
    if not npair:
        empty = np.zeros(0, dtype=np.int64)
        return _Pairs(empty, empty, empty, np.zeros(1, np.int64), empty, empty.reshape(0, d * d))
    others = np.array([[j for j in range(D) if j != i] for i in range(D)])  # spokes of a
    sf = others[ploc]  # (npair, d) the facets through a
    # a spoke is (patch, the facet's other vertices)
    _, spoke = np.unique(spoke_keys(table.gvert[prow], ploc, sf, patch), return_inverse=True)
    spoke = spoke.reshape(d, npair).T
    n_spokes = spoke.max() + 1
    spoke_patch = np.zeros(n_spokes, dtype=np.int64)
    spoke_patch[spoke] = patch[:, None]
    # (spoke, row) is unknown unless row r is prescribed-free (Dirichlet) on that facet
    skind = np.zeros((n_spokes, d), dtype=np.int8)
    skind[spoke] = kinds[prow[:, None], sf]
    unknown = (skind != DIRICHLET).reshape(-1)  # slots (spoke, row)
    slot_patch = np.repeat(spoke_patch, d)
    size = np.bincount(slot_patch[unknown], minlength=len(uniq))
    first = np.concatenate([[0], np.cumsum(size)[:-1]])
    local = np.full(n_spokes * d, -1)
    us = np.flatnonzero(unknown)
    local[us] = np.arange(len(us)) - first[slot_patch[us]]
    # the slot of each of the pair's d·B spoke rows: slot (spoke, row), moment k
    slot = (spoke[:, :, None] * d + np.arange(d)[None, None, :]).reshape(npair, d * d)
    pstart = np.searchsorted(patch, np.arange(len(uniq) + 1))
    return _Pairs(prow, ploc, patch, pstart, size, local[slot])


def _patches(pairs: _Pairs, ref, cells: _Cells, beta: np.ndarray, rows, alpha, kernel):
    """Assemble and solve the μ-systems of the patches ``pairs`` (module docstring; their
    ``prow`` index ``cells``, the operators of the cells ``rows``; ``beta``: (npair, d, np)
    the pairs' divergence moments); adds σ_a to ``alpha`` (rows ``rows``); returns the
    summed residual of the least-squares solves and the kernel's error code.  ``kernel``:
    None (NumPy, :func:`_multipliers`) or the compiled library of :mod:`.stress_c`."""
    d, nf = ref.d, ref.nf
    prow, ploc, loc = pairs.prow, pairs.ploc, pairs.loc
    npair = len(prow)
    gamma0 = cells.gamma0[prow, ploc]
    hp = cells.h[prow, ploc]  # (npair, D B): the normal moments of σ_a at μ = 0
    dp = cells.data[prow, ploc]
    if kernel is None:
        mu, defect = _multipliers(cells.S, prow, ploc, pairs.patch, pairs.size, loc, hp, dp, ref)
        err = 0
    else:
        idx = np.where(
            np.repeat(loc >= 0, nf, axis=1),
            (np.repeat(loc, nf, axis=1) * nf + np.tile(np.arange(nf), d * d)),
            -1,
        )  # (npair, d B): the patch-local unknown of each spoke moment
        mu, defect, err = stress_c.patch_multipliers(
            kernel, d, nf, pairs.pstart, prow, ploc, idx, pairs.size * nf, cells.S, hp, dp
        )
    # Σ_a σ_a|_T = R Σ_a β_a + Z Σ_a γ_a with γ_a = γ⁰_a − P Oᵀ μ_a: the pairs summed per
    # cell first, so P Oᵀ is applied once per cell
    n = len(rows)

    def per_cell(v: np.ndarray) -> np.ndarray:  # (npair, k) → (n, k): Σ over the cell's pairs
        return np.stack([np.bincount(prow, weights=c, minlength=n) for c in v.T], axis=1)

    mz = ref.Z.shape[1]
    gamma = per_cell(gamma0) - np.einsum("nyf,nf->ny", cells.POt, per_cell(mu))
    alpha[rows] += np.einsum(
        "nrj,lj->nrl", per_cell(beta.reshape(npair, -1)).reshape(n, d, -1), ref.R
    ) + np.einsum("nrz,lz->nrl", gamma.reshape(n, d, mz), ref.Z)
    return defect, err


def _multipliers(S, prow, ploc, patch, size, loc, hp, dp, ref: Reference):
    """The NumPy patch stage of :func:`_patches` (the reference of :mod:`.stress_c`): μ
    (npair, D d nf) of every pair and the summed defect; each size class of patches
    (``size``: unknown (spoke, row) slots) assembled and solved in one batched call."""
    d, D, nf = ref.d, ref.d + 1, ref.nf
    B = d * nf
    npair = len(prow)
    ar = np.arange(npair)
    others = np.array([[j for j in range(D) if j != i] for i in range(D)])
    # per pair: condense the opposite facet (its block: rows ploc·B … ploc·B + B − 1), for
    # each cell and local vertex at once (static index sets per local vertex)
    blocks = np.arange(D * B).reshape(D, B)
    I_o = blocks[ploc]  # (npair, B)
    I_s = blocks[others[ploc]].reshape(npair, d * B)
    Sso_all = np.empty((len(S), D, d * B, B))
    Soo_inv_all = np.empty((len(S), D, B, B))
    Shat_all = np.empty((len(S), D, d * B, d * B))
    for j in range(D):  # the cells' patches of their local vertex j
        i_s, i_o = blocks[others[j]].ravel(), blocks[j]
        Sso_all[:, j] = S[:, i_s][:, :, i_o]
        Soo_inv_all[:, j] = np.linalg.inv(S[:, i_o][:, :, i_o])
        Tj = Sso_all[:, j] @ Soo_inv_all[:, j]
        Shat_all[:, j] = S[:, i_s][:, :, i_s] - Tj @ np.transpose(Sso_all[:, j], (0, 2, 1))
    Sso, Soo_inv, Shat = Sso_all[prow, ploc], Soo_inv_all[prow, ploc], Shat_all[prow, ploc]
    T = Sso @ Soo_inv
    b = (hp[ar[:, None], I_s] - np.einsum("nab,nb->na", T, hp[ar[:, None], I_o])) - dp[
        ar[:, None], I_s
    ]
    idx = np.where(
        np.repeat(loc >= 0, nf, axis=1),
        (np.repeat(loc, nf, axis=1) * nf + np.tile(np.arange(nf), d * d)),
        -1,
    )  # (npair, d B)
    mu_s = np.zeros((npair, d * B))
    defect = 0.0
    for n_slots in np.unique(size[size > 0]):
        members = np.flatnonzero(size == n_slots)
        where = np.full(len(size), -1)
        where[members] = np.arange(len(members))
        sel = np.flatnonzero(where[patch] >= 0)
        dim = n_slots * nf
        pi, ii = where[patch[sel]], idx[sel]
        ok = ii >= 0
        rows = np.where(ok, ii, 0)
        # the pairs' blocks summed into the patch systems (slot = (spoke, row), nf moments)
        A, rhs = assemble_patches(pi, loc[sel], Shat[sel], b[sel], len(members), n_slots, nf)
        # the rigid motions of a closed patch span the kernel of A and the right-hand side
        # is orthogonal to them (up to the solve's residual): a shift of 1e-12 of the
        # diagonal's scale makes A regular; the kernel part of μ does not change σ_a
        # (P Oᵀ μ = 0 there) and what the shift leaves in A μ − b is reported
        shift = 1e-12 * np.abs(np.einsum("nii->n", A)).max(initial=0.0) / dim
        sol = np.linalg.solve(A + shift * np.eye(dim), rhs[..., None])[..., 0]
        defect += float(np.linalg.norm(np.einsum("nab,nb->na", A, sol) - rhs, axis=1).sum())
        got = sol[pi[:, None], rows]
        mu_s[sel] = np.where(ok, got, 0.0)
    mu_o = np.einsum(
        "nab,nb->na", Soo_inv, hp[ar[:, None], I_o] - np.einsum("nba,nb->na", Sso, mu_s)
    )
    mu = np.zeros((npair, D * B))
    mu[ar[:, None], I_s] = mu_s
    mu[ar[:, None], I_o] = mu_o
    return mu, defect
