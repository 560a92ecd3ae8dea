/* The vertex-patch μ-systems of the equilibrated stress (stress.py) in C: the same algebra
   as stress._cell_operators and stress._patch_multipliers, one cell and one patch at a time
   (built, verified and loaded by compiled.py; called by stress_c.py).

   Per pair (cell T of the patch of vertex a): the facet of T opposite a is condensed,

       X = S_oo⁻¹ S_os,   y = S_oo⁻¹ h_o,   Ŝ = S_ss − S_so X,   b = h_s − S_so y − d_s,

   the pairs' Ŝ and b are summed into the patch system A μ_s = b (the unknown (spoke, row)
   slots), which is solved by LU with partial pivoting after a shift of 1e-12 of its mean
   diagonal (a closed patch's rigid motions span the kernel of A; the kernel part of μ does
   not change σ_a), and μ_o = y − X μ_s.  The residual ‖A μ_s − b‖ of the unshifted system
   is summed into the defect.

   Compile-time constants (-D flags, one library per reference element:
   compiled.stress_dimensions): DIM d, NV d + 1, NF dim P_p(F), BF d NF, MZ, NP, NAS the
   d(d − 1)/2 skew pairs. */

#if !defined(DIM) || !defined(NV) || !defined(NF) || !defined(BF) || !defined(MZ) \
    || !defined(NP) || !defined(NAS)
#error "stress.c: compile with -DDIM=.. -DNV=.. -DNF=.. -DBF=.. -DMZ=.. -DNP=.. -DNAS=.. (compiled.stress_dimensions)"
#endif

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "stress.h"
#include "lu.h"

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
      /* the pair's rows: io those of the facet opposite a, is the spokes' (facets through a) */
      const int o = ploc[k];
      int is[SB], io[BF];
      for (int e = 0; e < BF; ++e) io[e] = o * BF + e;
      for (int f = 0, s = 0; f < NV; ++f)
        if (f != o)
          for (int e = 0; e < BF; ++e) is[s++] = f * BF + e;
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
