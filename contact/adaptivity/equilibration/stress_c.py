"""The vertex-patch μ-systems of the equilibrated stress (:mod:`.stress`) through a compiled
kernel: the same algebra as :func:`.stress._patch_multipliers`, one patch at a time in C.

Per pair (cell T of the patch of vertex a): the facet of T opposite a is condensed,

    X = S_oo⁻¹ S_os,   y = S_oo⁻¹ h_o,   Ŝ = S_ss − S_so X,   b = h_s − S_so y − d_s,

the pairs' Ŝ and b are summed into the patch system A μ_s = b (the unknown (spoke, row)
slots), which is solved by LU with partial pivoting after a shift of 1e-12 of its mean
diagonal (a closed patch's rigid motions span the kernel of A; the kernel part of μ does
not change σ_a), and μ_o = y − X μ_s.  The residual ‖A μ_s − b‖ of the unshifted system is
summed into the defect.  The NumPy reference shifts every patch of one size by the largest
mean diagonal among them; both shifts move only the kernel part, so σ_h agrees to round-off.

Why: NumPy spends most of the patch stage on fancy indexing and the scatter of the pairs'
blocks into batched patch matrices (hertz_2d, 64k DoFs: 8.9 s of a 17 s estimate); the
kernel spends what the flops cost.  The library is built and cached by :mod:`.compiled`
(one per (d, dim P_p(F))), with the LU of :mod:`.kernel_c`.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from .compiled import load
from .kernel_c import HEADERS, LU_SOLVE
from .reference import Reference

CDEF = """
int st_cells(int64_t n, const double *J, const double *s, const double *absdet, const double *ZZ,
             const double *ZR, const double *W, const double *M1Z, const double *M1R,
             const double *OZ, const double *OR, const double *q0, const double *beta,
             const double *mas, double *S, double *gamma0, double *h, double *POt);
int st_patches(int64_t npatch, const int64_t *pstart, const int64_t *prow, const int32_t *ploc,
               const int64_t *idx, const int64_t *pdim, const double *S, const double *hp,
               const double *dp, double *mu, double *defect);
"""

SOURCE = (
    HEADERS
    + CDEF
    + LU_SOLVE
    + r"""
/* NV facets per cell (d + 1), BF = d nf moments per facet block (rows × moments) */
#define DB (NV * BF)                     /* a cell's normal moments */
#define SB ((NV - 1) * BF)               /* the spokes of a pair: the facets through a */

#define DMZ (DIM * MZ)
#define DNP (DIM * NP)
#define NFV (NV * NF)                    /* a cell's normal moments of one row */

/* H = A⁻¹ for an SPD n × n matrix A through its Cholesky factor L: L⁻¹ by forward
   substitution, H = L⁻ᵀ L⁻¹ (a fraction of the flops of an LU with n right-hand sides);
   returns 1 at a non-positive pivot. */
static int spd_inv(int n, const double *A, double *H)
{
  double L[n * n], Li[n * n];
  for (int j = 0; j < n; ++j) {
    double d = A[j * n + j];
    for (int k = 0; k < j; ++k) d -= L[j * n + k] * L[j * n + k];
    if (!(d > 0.0)) return 1;
    L[j * n + j] = sqrt(d);
    for (int i = j + 1; i < n; ++i) {
      double v = A[i * n + j];
      for (int k = 0; k < j; ++k) v -= L[i * n + k] * L[j * n + k];
      L[i * n + j] = v / L[j * n + j];
    }
  }
  for (int j = 0; j < n; ++j) {
    Li[j * n + j] = 1.0 / L[j * n + j];
    for (int i = j + 1; i < n; ++i) {
      double v = 0.0;
      for (int k = j; k < i; ++k) v += L[i * n + k] * Li[k * n + j];
      Li[i * n + j] = -v / L[i * n + i];
    }
  }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j <= i; ++j) {
      double v = 0.0;
      for (int k = i; k < n; ++k) v += Li[k * n + i] * Li[k * n + j];
      H[i * n + j] = H[j * n + i] = v;
    }
  return 0;
}

/* The cell operators of :func:`.stress._cell_operators`, cell by cell (the same algebra; the
   index conventions of the NumPy arrays, row-major). */
int st_cells(int64_t n, const double *J, const double *s, const double *absdet, const double *ZZ,
             const double *ZR, const double *W, const double *M1Z, const double *M1R,
             const double *OZ, const double *OR, const double *q0, const double *beta,
             const double *mas, double *S, double *gamma0, double *h, double *POt)
{
  static const int pi[3] = {1, 2, 0}, pj[3] = {2, 0, 1};   /* the skew pairs (i, j) */
  for (int64_t c = 0; c < n; ++c) {
    const double *Jc = J + c * DIM * DIM, *OZc = OZ + c * NFV * MZ, *ORc = OR + c * NFV * NP;
    double coef[DIM][DIM][DIM][DIM], MZm[DMZ * DMZ], H[DMZ * DMZ], ZMR[DMZ * DNP];
    /* coef[r][s][i][j] = Σ_tu W[r][s][t][u] J_ti J_uj / |det J| */
    for (int r = 0; r < DIM; ++r) for (int q = 0; q < DIM; ++q)
      for (int i = 0; i < DIM; ++i) for (int j = 0; j < DIM; ++j) {
        double v = 0.0;
        for (int t = 0; t < DIM; ++t) for (int u = 0; u < DIM; ++u)
          v += W[((r * DIM + q) * DIM + t) * DIM + u] * Jc[t * DIM + i] * Jc[u * DIM + j];
        coef[r][q][i][j] = v / absdet[c];
      }
    for (int r = 0; r < DIM; ++r) for (int q = 0; q < DIM; ++q)
      for (int a = 0; a < MZ; ++a) {
        for (int b = 0; b < MZ; ++b) {
          double v = 0.0;
          for (int i = 0; i < DIM; ++i) for (int j = 0; j < DIM; ++j)
            v += coef[r][q][i][j] * ZZ[((i * DIM + j) * MZ + a) * MZ + b];
          MZm[(r * MZ + a) * DMZ + q * MZ + b] = v;
        }
        for (int b = 0; b < NP; ++b) {
          double v = 0.0;
          for (int i = 0; i < DIM; ++i) for (int j = 0; j < DIM; ++j)
            v += coef[r][q][i][j] * ZR[((i * DIM + j) * MZ + a) * NP + b];
          ZMR[(r * MZ + a) * DNP + q * NP + b] = v;
        }
      }
    if (spd_inv(DMZ, MZm, H)) return 1;                     /* H = M_Z⁻¹ */
    /* a_Z, a_R: ∫_T σ_ij − σ_ji = s (J M1 Z)_j·γ_i − s (J M1 Z)_i·γ_j (+ R β alike) */
    double JZ[DIM][MZ], JR[DIM][NP], aZ[NAS][DMZ], aR[NAS][DNP];
    for (int q = 0; q < DIM; ++q) {
      for (int z = 0; z < MZ; ++z) {
        double v = 0.0;
        for (int k = 0; k < DIM; ++k) v += Jc[q * DIM + k] * M1Z[k * MZ + z];
        JZ[q][z] = s[c] * v;
      }
      for (int z = 0; z < NP; ++z) {
        double v = 0.0;
        for (int k = 0; k < DIM; ++k) v += Jc[q * DIM + k] * M1R[k * NP + z];
        JR[q][z] = s[c] * v;
      }
    }
    for (int k = 0; k < NAS; ++k) {
      const int i = NAS == 1 ? 0 : pi[k], j = NAS == 1 ? 1 : pj[k];
      for (int x = 0; x < DMZ; ++x) aZ[k][x] = 0.0;
      for (int x = 0; x < DNP; ++x) aR[k][x] = 0.0;
      for (int z = 0; z < MZ; ++z) { aZ[k][i * MZ + z] += JZ[j][z]; aZ[k][j * MZ + z] -= JZ[i][z]; }
      for (int z = 0; z < NP; ++z) { aR[k][i * NP + z] += JR[j][z]; aR[k][j * NP + z] -= JR[i][z]; }
    }
    /* H a_Zᵀ, G = a_Z H a_Zᵀ, H a_Zᵀ G⁻¹, P = H − H a_Zᵀ G⁻¹ a_Z H */
    double HaT[DMZ][NAS], G[NAS * NAS], Gi[NAS * NAS], HaG[DMZ][NAS], P[DMZ * DMZ];
    for (int x = 0; x < DMZ; ++x) for (int k = 0; k < NAS; ++k) {
      double v = 0.0;
      for (int y = 0; y < DMZ; ++y) v += H[x * DMZ + y] * aZ[k][y];
      HaT[x][k] = v;
    }
    for (int k = 0; k < NAS; ++k) for (int l = 0; l < NAS; ++l) {
      double v = 0.0;
      for (int x = 0; x < DMZ; ++x) v += aZ[k][x] * HaT[x][l];
      G[k * NAS + l] = v;
      Gi[k * NAS + l] = k == l;
    }
    if (lu_solve(NAS, G, Gi, NAS)) return 1;
    for (int x = 0; x < DMZ; ++x) for (int k = 0; k < NAS; ++k) {
      double v = 0.0;
      for (int l = 0; l < NAS; ++l) v += HaT[x][l] * Gi[l * NAS + k];
      HaG[x][k] = v;
    }
    for (int x = 0; x < DMZ; ++x) for (int y = 0; y < DMZ; ++y) {
      double v = H[x * DMZ + y];
      for (int k = 0; k < NAS; ++k) v -= HaG[x][k] * HaT[y][k];
      P[x * DMZ + y] = v;
    }
    /* P Oᵀ (rows (r, z), columns (f, q, k)) and S = O P Oᵀ; O is block diagonal in the rows */
    double *POc = POt + c * DMZ * DB, *Sc = S + c * DB * DB, OHaG[DB][NAS];
    for (int x = 0; x < DMZ; ++x)
      for (int f = 0; f < NV; ++f) for (int q = 0; q < DIM; ++q) for (int k = 0; k < NF; ++k) {
        double v = 0.0;
        for (int z = 0; z < MZ; ++z) v += P[x * DMZ + q * MZ + z] * OZc[(f * NF + k) * MZ + z];
        POc[x * DB + (f * DIM + q) * NF + k] = v;
      }
    for (int f = 0; f < NV; ++f) for (int r = 0; r < DIM; ++r) for (int k = 0; k < NF; ++k) {
      const int row = (f * DIM + r) * NF + k;
      for (int col = 0; col < DB; ++col) {
        double v = 0.0;
        for (int z = 0; z < MZ; ++z) v += OZc[(f * NF + k) * MZ + z] * POc[(r * MZ + z) * DB + col];
        Sc[row * DB + col] = v;
      }
      for (int kk = 0; kk < NAS; ++kk) {
        double v = 0.0;
        for (int z = 0; z < MZ; ++z) v += OZc[(f * NF + k) * MZ + z] * HaG[r * MZ + z][kk];
        OHaG[row][kk] = v;
      }
    }
    /* per vertex a: q = q⁰ − Z_bᵀ M R_b β, P q, c = m − a_R β, γ⁰ = P q + H a_Zᵀ G⁻¹ c,
       h = O R_b β + O Z_b P q + O H a_Zᵀ G⁻¹ c */
    for (int a = 0; a < NV; ++a) {
      const double *bc = beta + (c * NV + a) * DNP, *qc = q0 + (c * NV + a) * DMZ;
      const double *mc = mas + (c * NV + a) * NAS;
      double qv[DMZ], Pq[DMZ], cc[NAS];
      for (int x = 0; x < DMZ; ++x) {
        double v = qc[x];
        for (int b = 0; b < DNP; ++b) v -= ZMR[x * DNP + b] * bc[b];
        qv[x] = v;
      }
      for (int x = 0; x < DMZ; ++x) {
        double v = 0.0;
        for (int y = 0; y < DMZ; ++y) v += P[x * DMZ + y] * qv[y];
        Pq[x] = v;
      }
      for (int k = 0; k < NAS; ++k) {
        double v = mc[k];
        for (int b = 0; b < DNP; ++b) v -= aR[k][b] * bc[b];
        cc[k] = v;
      }
      double *gc = gamma0 + (c * NV + a) * DMZ, *hc = h + (c * NV + a) * DB;
      for (int x = 0; x < DMZ; ++x) {
        double v = Pq[x];
        for (int k = 0; k < NAS; ++k) v += HaG[x][k] * cc[k];
        gc[x] = v;
      }
      for (int f = 0; f < NV; ++f) for (int r = 0; r < DIM; ++r) for (int k = 0; k < NF; ++k) {
        const int row = (f * DIM + r) * NF + k;
        double v = 0.0;
        for (int j = 0; j < NP; ++j) v += ORc[(f * NF + k) * NP + j] * bc[r * NP + j];
        for (int z = 0; z < MZ; ++z) v += OZc[(f * NF + k) * MZ + z] * Pq[r * MZ + z];
        for (int kk = 0; kk < NAS; ++kk) v += OHaG[row][kk] * cc[kk];
        hc[row] = v;
      }
    }
  }
  return 0;
}

int st_patches(int64_t npatch, const int64_t *pstart, const int64_t *prow, const int32_t *ploc,
               const int64_t *idx, const int64_t *pdim, const double *S, const double *hp,
               const double *dp, double *mu, double *defect)
{
  int64_t maxpair = 0, maxdim = 0;
  for (int64_t p = 0; p < npatch; ++p) {
    if (pstart[p + 1] - pstart[p] > maxpair) maxpair = pstart[p + 1] - pstart[p];
    if (pdim[p] > maxdim) maxdim = pdim[p];
  }
  double *X = malloc(sizeof(double) * (maxpair * BF * (SB + 1) + 2 * maxdim * maxdim
                                       + 2 * maxdim + 1));
  if (!X) return 3;
  double *A = X + maxpair * BF * (SB + 1), *A0 = A + maxdim * maxdim, *rhs = A0 + maxdim * maxdim;
  double *sol = rhs + maxdim;
  int err = 0;
  *defect = 0.0;
  for (int64_t p = 0; p < npatch && !err; ++p) {
    const int dim = (int)pdim[p];
    memset(A, 0, sizeof(double) * dim * dim);
    memset(rhs, 0, sizeof(double) * dim);
    for (int64_t k = pstart[p]; k < pstart[p + 1]; ++k) {
      const double *Sc = S + prow[k] * DB * DB, *h = hp + k * DB, *dk = dp + k * DB;
      const int64_t *ik = idx + k * SB;
      int is[SB], io[BF];
      for (int f = 0, s = 0; f < NV; ++f)
        for (int e = 0; e < BF; ++e) {
          if (f == ploc[k]) io[e] = f * BF + e;
          else is[s++] = f * BF + e;
        }
      double Soo[BF * BF], *Xk = X + (k - pstart[p]) * BF * (SB + 1);
      for (int e = 0; e < BF; ++e) {
        for (int g = 0; g < BF; ++g) Soo[e * BF + g] = Sc[io[e] * DB + io[g]];
        for (int j = 0; j < SB; ++j) Xk[e * (SB + 1) + j] = Sc[io[e] * DB + is[j]];
        Xk[e * (SB + 1) + SB] = h[io[e]];
      }
      if (lu_solve(BF, Soo, Xk, SB + 1)) { err = 1; break; }
      for (int i = 0; i < SB; ++i) {
        if (ik[i] < 0) continue;
        double b = h[is[i]] - dk[is[i]];
        for (int e = 0; e < BF; ++e) b -= Sc[is[i] * DB + io[e]] * Xk[e * (SB + 1) + SB];
        rhs[ik[i]] += b;
        for (int j = 0; j < SB; ++j) {
          if (ik[j] < 0) continue;
          double a = Sc[is[i] * DB + is[j]];
          for (int e = 0; e < BF; ++e) a -= Sc[is[i] * DB + io[e]] * Xk[e * (SB + 1) + j];
          A[ik[i] * dim + ik[j]] += a;
        }
      }
    }
    if (err) break;
    double trace = 0.0;
    for (int i = 0; i < dim; ++i) trace += fabs(A[i * dim + i]);
    memcpy(A0, A, sizeof(double) * dim * dim);
    memcpy(sol, rhs, sizeof(double) * dim);
    for (int i = 0; i < dim; ++i) A[i * dim + i] += 1e-12 * trace / dim;
    if (dim && lu_solve(dim, A, sol, 1)) { err = 2; break; }
    double res = 0.0;
    for (int i = 0; i < dim; ++i) {
      double r = -rhs[i];
      for (int j = 0; j < dim; ++j) r += A0[i * dim + j] * sol[j];
      res += r * r;
    }
    *defect += sqrt(res);
    for (int64_t k = pstart[p]; k < pstart[p + 1]; ++k) {
      const int64_t *ik = idx + k * SB;
      const double *Xk = X + (k - pstart[p]) * BF * (SB + 1);
      double *m = mu + k * DB, ms[SB];
      for (int f = 0, s = 0; f < NV; ++f)
        for (int e = 0; e < BF; ++e) {
          if (f == ploc[k]) continue;
          ms[s] = ik[s] >= 0 ? sol[ik[s]] : 0.0;
          m[f * BF + e] = ms[s];
          ++s;
        }
      for (int e = 0; e < BF; ++e) {
        double v = Xk[e * (SB + 1) + SB];
        for (int j = 0; j < SB; ++j) v -= Xk[e * (SB + 1) + j] * ms[j];
        m[ploc[k] * BF + e] = v;
      }
    }
  }
  free(X);
  return err;
}
"""
)


def library(comm: MPI.Comm, ref: Reference):
    """(ffi, lib) of the kernel for the rows' reference element ``ref`` (collective)."""
    d = ref.d
    dims = {"DIM": d, "NV": d + 1, "NF": ref.nf, "BF": d * ref.nf, "MZ": ref.Z.shape[1]}
    dims.update(NP=ref.np_, NAS=d * (d - 1) // 2)
    return load(comm, "stress", CDEF, SOURCE, dims)


def _ptr(ffi, keep: list, a: np.ndarray, ctype: str = "double"):
    """A C pointer to ``a`` (contiguous, of ``ctype``), kept alive in ``keep``."""
    dtype = {"double": np.float64, "int64_t": np.int64, "int32_t": np.int32}[ctype]
    a = np.ascontiguousarray(a, dtype=dtype)
    keep.append(a)
    return ffi.cast(f"{ctype} *", ffi.from_buffer(a))


def cell_operators(kernel: tuple, ref: Reference, arrays: dict, out: dict) -> int:
    """The per-cell arrays of :func:`.stress._cell_operators` (``out``: S, gamma0, h, POt,
    C-contiguous, written in place) from its inputs (``arrays``: J, s, absdet, the
    reference tables ZZ, ZR, W, M1Z, M1R, the oriented OZ, OR, and q0, beta, m); the
    kernel's error code (1: a singular cell matrix)."""
    ffi, lib = kernel
    keep: list = []
    names = ("J", "s", "absdet", "ZZ", "ZR", "W", "M1Z", "M1R", "OZ", "OR", "q0", "beta", "m")
    args = [_ptr(ffi, keep, arrays[k]) for k in names]
    for k in ("S", "gamma0", "h", "POt"):
        assert out[k].flags.c_contiguous and out[k].dtype == np.float64
        args.append(ffi.cast("double *", ffi.from_buffer(out[k])))
    return int(lib.st_cells(len(arrays["s"]), *args))


def patch_multipliers(
    kernel: tuple,
    d: int,
    nf: int,
    pstart: np.ndarray,
    prow: np.ndarray,
    ploc: np.ndarray,
    idx: np.ndarray,
    pdim: np.ndarray,
    S: np.ndarray,
    hp: np.ndarray,
    dp: np.ndarray,
) -> tuple[np.ndarray, float, int]:
    """μ (npair, D·d·nf) of every pair and the summed defect (module docstring).  The pairs
    are sorted by patch (``pstart``: the offsets, ``pdim``: each patch's unknowns);
    ``prow``/``ploc``: the pair's cell (a row of ``S`` (n, D d nf, D d nf)) and local
    vertex; ``idx`` (npair, d·d·nf): the patch-local unknown of each spoke moment, −1
    where the row is prescribed; ``hp``, ``dp``: the normal moments at μ = 0 and the
    prescribed data, (npair, D d nf); ``kernel``: :func:`library`'s (ffi, lib).  Returns
    μ, the defect and the kernel's error code (0: none; 1: a singular cell block, 2: a
    singular patch system, 3: out of memory): the caller decides collectively."""
    ffi, lib = kernel
    keep: list = []
    mu = np.zeros((len(prow), (d + 1) * d * nf))
    defect = np.zeros(1)
    err = lib.st_patches(
        len(pdim),
        _ptr(ffi, keep, pstart, "int64_t"),
        _ptr(ffi, keep, prow, "int64_t"),
        _ptr(ffi, keep, ploc, "int32_t"),
        _ptr(ffi, keep, idx, "int64_t"),
        _ptr(ffi, keep, pdim, "int64_t"),
        _ptr(ffi, keep, S),
        _ptr(ffi, keep, hp),
        _ptr(ffi, keep, dp),
        ffi.cast("double *", ffi.from_buffer(mu)),
        ffi.cast("double *", ffi.from_buffer(defect)),
    )
    return mu, float(defect[0]), int(err)
