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

CDEF = """
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


def library(comm: MPI.Comm, d: int, nf: int):
    """(ffi, lib) of the kernel for cells of dimension ``d`` with ``nf`` moments per facet
    and row (collective)."""
    return load(comm, "stress", CDEF, SOURCE, {"NV": d + 1, "BF": d * nf})


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
    keep = []

    def ptr(a, ctype):
        keep.append(a)
        return ffi.cast(f"{ctype} *", ffi.from_buffer(a))

    def f64(a):
        return ptr(np.ascontiguousarray(a, dtype=np.float64), "double")

    def i64(a):
        return ptr(np.ascontiguousarray(a, dtype=np.int64), "int64_t")

    mu = np.zeros((len(prow), (d + 1) * d * nf))
    defect = np.zeros(1)
    err = lib.st_patches(
        len(pdim),
        i64(pstart),
        i64(prow),
        ptr(np.ascontiguousarray(ploc, dtype=np.int32), "int32_t"),
        i64(idx),
        i64(pdim),
        f64(S),
        f64(hp),
        f64(dp),
        ptr(mu, "double"),
        ptr(defect, "double"),
    )
    return mu, float(defect[0]), int(err)
