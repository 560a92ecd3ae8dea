/* The compiled patch solver of the flux reconstruction: the algebra of operators.py and
   patches.py, cell by cell and patch by patch, in plain C99 (built, verified and loaded by
   compiled.py; called by patches_c.py).

   The dimensions of the reference element are compile-time constants (-D flags, one library
   per reference element: compiled.dimensions), so the compiler unrolls the small loops:

       DIM  d              NV   d + 1 (vertices = facets)     NQ, NQF  cell / facet points
       NU   dim P_p        M    dim RT_p     NP  dim P_p (div moments)    MZ  M − NP
       NF   dim P_p(F)     NPERM  d!        NLOOK  d^d (facet-permutation codes)
       LOWEST  1 for the lowest-order flux of a P1 solution (p = 0, NU = d + 1): each patch is
               fitted to the RT_0 interpolant of ψ_a w (target_lanes; docs/theory.md §9)

   cell_block computes, for LB cells at once (SIMD lanes), the operators the patch problems
   need (a work row: W_* below) and osc_T; eq_patches solves the patch of every vertex of a
   global index range and adds σ_a|_T to alpha.  The load Zᵀg_a is a table contraction where
   k is one constant and the target flux is k∇ of a function of the element of u_h, else a
   sum over the quadrature points.  A patch system is ordered by reverse Cuthill–McKee and
   factorized by Cholesky in batches of LB systems of one size (SIMD lanes: dense up to
   DENSE dofs, else in the union of the lanes' envelopes — the spokes of a 3D patch couple
   only through the cells they share); a patch without a Dirichlet spoke has the constant
   multiplier as its kernel: one constant moment is pinned and the solution projected
   orthogonal to the kernel, which is the solution of the regularized system of patches.py.
   Where the Cholesky meets a non-positive pivot the patch falls back to that regularized
   system and an LU factorization with partial pivoting.

   eq_flow (backend "flow", P1) runs the same driver with a cheaper fit.  For p = 1 a flux in
   RT_p(T) is determined by its facet moments and divergence moments (σ̂ = GL m̂ + RL β), so
   σ_a is sought in the reference facet moments m̂ of each pair's cell: flow_block computes
   the cell's energy ½‖σ_a − ψ_a τ‖²_{k_T⁻¹} = ½ m̂ᵀA m̂ − b_aᵀm̂ + const (no inverse per
   cell), and solve_flow descends it patch by patch in blocks: the constant fluxes of the
   spokes, on which all the constraints act (a spoke system with the sparsity of the patch's
   spoke graph, factorized once), then, `rounds` times, the higher moments spoke by spoke
   (unconstrained) and the constant fluxes again, from the higher moments of the mean of the
   two cells' ψ_a τ̄.  Every iterate has the divergence and normal data of the reference, so
   the bound stays guaranteed; the rounds converge to the reference minimizer
   (tests/test_equilibration_backends.py).

   Return codes: 0 ok, 1 a singular cell matrix, 2 a singular patch system, 3 out of memory.

   The per-cell work row of cell_block, in this order: Yt (DNF*MZ) and C (M), with σ_h|_T =
   C − Z Ytᵀ Σ_a μ_a; then per vertex a (contiguous: what its patch reads) the condensed
   patch block Ŝ_a (SYM, packed lower triangle), its load b_a (SNF), and T_a (NF*SNF), ho_a
   (NF), with μ_o = ho_a − T_a μ_s. */

#if !defined(DIM) || !defined(NV) || !defined(NQ) || !defined(NQF) || !defined(NU) \
    || !defined(M) || !defined(NP) || !defined(MZ) || !defined(NF) || !defined(NPERM) \
    || !defined(NLOOK) || !defined(LOWEST)
#error "eqlb.c: compile with -DDIM=.. -DNV=.. -DNQ=.. -DNQF=.. -DNU=.. -DM=.. -DNP=.. -DMZ=.. -DNF=.. -DNPERM=.. -DNLOOK=.. -DLOWEST=.. (compiled.dimensions)"
#endif

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "eqlb.h"
#include "lu.h"


#define PI_ 3.14159265358979323846
#define MAXN (MZ > NF ? MZ : NF)
#define MAXB (NP > NF ? NP : NF)
#define DNF (NV * NF)
#define SNF (DIM * NF)
enum { INTERIOR = 0, DIRICHLET = 1, FLUX = 2, CONTACT = 3 };

/* the work row of a cell: what the patch systems (per vertex a: the condensed Ŝ_a, b_a and
   μ_o = ho_a − Ta_a μ_s) and the final map to alpha need: σ_h|_T = Σ_a σ_a|_T, σ_a|_T =
   R β_a + Z M_Z⁻¹ (Zᵀg_a − ZMR β_a − (O Z)ᵀ μ_a) is C − Z Ytᵀ Σ_a μ_a with Yt = (O Z) M_Z⁻¹
   and C the rest, summed over the vertices a whose patches are solved here */
#define W_YT 0
#define W_C (W_YT + DNF * MZ)
#define SYM (SNF * (SNF + 1) / 2)      /* a packed symmetric SNF x SNF matrix */
#define SYMIDX(i, j) ((i) >= (j) ? (i) * ((i) + 1) / 2 + (j) : (j) * ((j) + 1) / 2 + (i))
/* per vertex a, contiguous (what its patch reads): Ŝ_a (packed lower triangle), b_a, T_a, ho_a */
#define A_B SYM
#define A_TA (A_B + SNF)
#define A_HO (A_TA + NF * SNF)
#define A_SIZE (A_HO + NF)
#define W_A(a) (W_C + M + (a) * A_SIZE)
#define W_SIZE W_A(NV)
/* the work row of flow_block (the moment path): per vertex a the divergence moments β_a and
   the data moments, s, the facet permutations, the cell's energy in its reference facet
   moments (A, DNF x DNF), per vertex a the load b_a (DNF) and the outward moments of ψ_a τ̄
   on every facet (global bases); the patches' scratch per pair: FA_* (flow_pair) */
#define FW_DATA (NV * NP)
#define FW_S (FW_DATA + NV * NV * NF)
#define FW_PERM (FW_S + 1)
#define FW_AM (FW_PERM + NV)
#define FW_B (FW_AM + DNF * DNF)
#define FW_TM (FW_B + NV * DNF)
#define FW_SIZE (FW_TM + NV * NV * NF)
#define FA_P 0
#define NH (NF > 1 ? NF - 1 : 1)      /* the higher moments of a facet */
#define FA_Q (DIM * DIM)
#define FA_H (FA_Q + DIM)
#define FA_F (FA_H + DIM)
#define FA_G (FA_F + DIM)
#define FA_SIZE (FA_G + 1)
#define DENSE 24                        /* patch systems up to this size: no reordering */
#define LB 8                            /* cells per block: the SIMD lanes of cell_block */
#define LANES for (int b = 0; b < LB; ++b)

int64_t eq_work_size(void) { return W_SIZE; }


static double det_inv(const double J[DIM][DIM], double Ji[DIM][DIM])
{
#if DIM == 2
  double det = J[0][0] * J[1][1] - J[0][1] * J[1][0];
  Ji[0][0] = J[1][1] / det; Ji[1][1] = J[0][0] / det;
  Ji[0][1] = -J[0][1] / det; Ji[1][0] = -J[1][0] / det;
#else
  double adj[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      int r0 = (j + 1) % 3, r1 = (j + 2) % 3, c0 = (i + 1) % 3, c1 = (i + 2) % 3;
      if (r0 > r1) { int s = r0; r0 = r1; r1 = s; }
      if (c0 > c1) { int s = c0; c0 = c1; c1 = s; }
      double minor = J[r0][c0] * J[r1][c1] - J[r0][c1] * J[r1][c0];
      adj[i][j] = ((i + j) % 2 ? -1.0 : 1.0) * minor;
    }
  double det = J[0][0] * adj[0][0] + J[0][1] * adj[1][0] + J[0][2] * adj[2][0];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) Ji[i][j] = adj[i][j] / det;
#endif
  return det;
}

/* |F| / |F^| of facet j (the vertices other than j): sqrt(det(E E^T)) */
static double facet_size(const double *x, int j)
{
  int o[NV - 1], n = 0;
  for (int v = 0; v < NV; ++v) if (v != j) o[n++] = v;
  double E[DIM - 1][DIM];
  for (int a = 0; a < DIM - 1; ++a)
    for (int i = 0; i < DIM; ++i) E[a][i] = x[o[a + 1] * DIM + i] - x[o[0] * DIM + i];
  double G[DIM - 1][DIM - 1];
  for (int a = 0; a < DIM - 1; ++a)
    for (int b = 0; b < DIM - 1; ++b) {
      double s = 0.0;
      for (int i = 0; i < DIM; ++i) s += E[a][i] * E[b][i];
      G[a][b] = s;
    }
#if DIM == 2
  double det = G[0][0];
#else
  double det = G[0][0] * G[1][1] - G[0][1] * G[1][0];
#endif
  return sqrt(fabs(det));
}

static int facet_perm(const eq_ref *r, const int64_t *g, int j)
{
  int64_t o[NV - 1];
  int n = 0;
  for (int v = 0; v < NV; ++v) if (v != j) o[n++] = g[v];
  int64_t code = 0;
  for (int a = 0; a < NV - 1; ++a) {
    int rank = 0;
    for (int b = 0; b < NV - 1; ++b) rank += o[b] < o[a];
    code = code * (NV - 1) + rank;
  }
  return (int)r->lookup[code];
}

/* ‖v − Π v‖² by the rule (w, nq): Π the projection onto the nb orthonormal B (nb, nq). */
static double l2_rest(const double *v, const double *w, const double *B, int nq, int nb)
{
  double mom[MAXB], rest = 0.0;
  for (int a = 0; a < nb; ++a) {
    double s = 0.0;
    for (int q = 0; q < nq; ++q) s += v[q] * w[q] * B[a * nq + q];
    mom[a] = s;
  }
  for (int q = 0; q < nq; ++q) {
    double e = v[q];
    for (int a = 0; a < nb; ++a) e -= mom[a] * B[a * nq + q];
    rest += e * e * w[q];
  }
  return rest;
}

static double oscillation(const eq_ref *r, const eq_table *t, int64_t c, double absdet,
                          const double size[][LB], int lane)
{
  const double *x = t->x + c * NV * DIM, *f = t->f + c * t->fstride, *k = t->k + c * t->kstride;
  double fact = 1.0, fact1 = 1.0;
  for (int i = 2; i <= DIM; ++i) fact *= i;
  for (int i = 2; i <= DIM - 1; ++i) fact1 *= i;
  double vol = absdet / fact, h = 0.0;
  for (int i = 0; i < NV; ++i)
    for (int j = 0; j < i; ++j) {
      double s = 0.0;
      for (int l = 0; l < DIM; ++l) { double e = x[i * DIM + l] - x[j * DIM + l]; s += e * e; }
      if (sqrt(s) > h) h = sqrt(s);
    }
  double rest = l2_rest(f, r->w, r->Q, NQ, NP);
  double osc = h / PI_ * sqrt(fmax(absdet * rest, 0.0));
  for (int j = 0; j < NV; ++j) {
    int kind = t->kind[c * NV + j];
    if (kind != FLUX && kind != CONTACT) continue;   /* no data there: t = 0 in the table */
    const double *tj = t->t + (c * NV + j) * NQF;
    double tr = l2_rest(tj, r->wS, r->q, NQF, NF);
    double area = size[j][lane] / fact1, norm = sqrt(size[j][lane] * tr);
    osc += h * sqrt(area / vol * (1.0 / (PI_ * PI_) + 2.0 / (DIM * PI_))) * norm;
  }
  double kmin = k[0];
  for (int q = 1; q < NQ; ++q) kmin = fmin(kmin, k[q]);
  return osc / sqrt(kmin);
}

/* SPD inverses of LB n x n matrices at once (entry (i, j) of lane b at [(i n + j) LB + b]) by
   Cholesky; a lane with a non-positive pivot is inverted by LU instead. */
static int spd_inverse_lanes(int n, const double *restrict A, double *restrict Ainv)
{
  double L[MAXN * MAXN][LB], Li[MAXN * MAXN][LB], Ld[MAXN][LB];   /* Ld: 1 / L_ii */
  int bad[LB] = {0};
  if (n == 1) {
    LANES { if (!(A[b] > 0.0)) bad[b] = 1; Ainv[b] = 1.0 / A[b]; }
    goto fallback;
  }
  if (n == 2) {
    LANES {
      double a = A[b], c = A[LB + b], d = A[3 * LB + b], det = a * d - c * c;
      if (!(a > 0.0 && det > 0.0)) bad[b] = 1;
      det = 1.0 / det;
      Ainv[b] = d * det; Ainv[LB + b] = Ainv[2 * LB + b] = -c * det; Ainv[3 * LB + b] = a * det;
    }
    goto fallback;
  }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j <= i; ++j) {
      double v[LB];
      LANES v[b] = A[(i * n + j) * LB + b];
      for (int k = 0; k < j; ++k) LANES v[b] -= L[i * MAXN + k][b] * L[j * MAXN + k][b];
      if (i == j) {
        LANES {
          if (!(v[b] > 0.0)) { bad[b] = 1; v[b] = 1.0; }
          L[i * MAXN + i][b] = sqrt(v[b]);
          Ld[i][b] = 1.0 / L[i * MAXN + i][b];
        }
      } else {
        LANES L[i * MAXN + j][b] = v[b] * Ld[j][b];
      }
    }
  for (int j = 0; j < n; ++j)
    for (int i = j; i < n; ++i) {
      double v[LB];
      LANES v[b] = i == j ? 1.0 : 0.0;
      for (int k = j; k < i; ++k) LANES v[b] -= L[i * MAXN + k][b] * Li[k * MAXN + j][b];
      LANES Li[i * MAXN + j][b] = v[b] * Ld[i][b];
    }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j <= i; ++j) {
      double v[LB] = {0.0};
      for (int k = i; k < n; ++k) LANES v[b] += Li[k * MAXN + i][b] * Li[k * MAXN + j][b];
      LANES Ainv[(i * n + j) * LB + b] = Ainv[(j * n + i) * LB + b] = v[b];
    }
fallback:
  for (int b = 0; b < LB; ++b) {
    if (!bad[b]) continue;
    double a[MAXN * MAXN], ai[MAXN * MAXN];
    for (int k = 0; k < n * n; ++k) a[k] = A[k * LB + b];
    memset(ai, 0, sizeof(double) * n * n);
    for (int k = 0; k < n; ++k) ai[k * n + k] = 1.0;
    if (lu_solve(n, a, ai, n)) return 1;
    for (int k = 0; k < n * n; ++k) Ainv[k * LB + b] = ai[k];
  }
  return 0;
}

/* ---------------------------------------------------------------------------------- */
/* lane helpers shared by cell_block and flow_block (LB cells cl[b] at once)           */
/* ---------------------------------------------------------------------------------- */
static inline void load_lanes(const eq_table *restrict t, const int64_t *cl, double X[][LB],
                              double K[][LB], double F[][LB], double Uc[][LB])
{
  for (int v = 0; v < NV * DIM; ++v) LANES X[v][b] = t->x[cl[b] * NV * DIM + v];
  for (int q = 0; q < NQ; ++q)
    LANES { K[q][b] = t->k[cl[b] * t->kstride + q]; F[q][b] = t->f[cl[b] * t->fstride + q]; }
  for (int u = 0; u < NU; ++u) LANES Uc[u][b] = t->U[cl[b] * NU + u];
}

/* J (x = x_0 + J x̂), J⁻¹, det J, s = sign det J and |det J| */
static inline void geometry_lanes(const double X[][LB], double J[][DIM][LB], double Ji[][DIM][LB],
                                  double *det, double *s, double *absdet)
{
  for (int i = 0; i < DIM; ++i)
    for (int j = 0; j < DIM; ++j) LANES J[i][j][b] = X[(j + 1) * DIM + i][b] - X[i][b];
#if DIM == 2
  LANES {
    det[b] = J[0][0][b] * J[1][1][b] - J[0][1][b] * J[1][0][b];
    Ji[0][0][b] = J[1][1][b] / det[b]; Ji[1][1][b] = J[0][0][b] / det[b];
    Ji[0][1][b] = -J[0][1][b] / det[b]; Ji[1][0][b] = -J[1][0][b] / det[b];
  }
#else
  double adj[3][3][LB];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      int r0 = (j + 1) % 3, r1 = (j + 2) % 3, c0 = (i + 1) % 3, c1 = (i + 2) % 3;
      if (r0 > r1) { int u = r0; r0 = r1; r1 = u; }
      if (c0 > c1) { int u = c0; c0 = c1; c1 = u; }
      double sg = (i + j) % 2 ? -1.0 : 1.0;
      LANES adj[i][j][b] = sg * (J[r0][c0][b] * J[r1][c1][b] - J[r0][c1][b] * J[r1][c0][b]);
    }
  LANES det[b] = J[0][0][b] * adj[0][0][b] + J[0][1][b] * adj[1][0][b] + J[0][2][b] * adj[2][0][b];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) LANES Ji[i][j][b] = adj[i][j][b] / det[b];
#endif
  LANES { s[b] = (det[b] > 0) - (det[b] < 0); absdet[b] = fabs(det[b]); }
}

/* GM = Jᵀ J / |det J| and KS = J⁻¹ J⁻ᵀ |det J| */
static inline void metric_lanes(const double J[][DIM][LB], const double Ji[][DIM][LB],
                                const double *absdet, double GM[][LB], double KS[][DIM][LB])
{
  for (int i = 0; i < DIM; ++i)
    for (int j = 0; j < DIM; ++j) {
      double g[LB] = {0.0}, h[LB] = {0.0};
      for (int l = 0; l < DIM; ++l)
        LANES { g[b] += J[l][i][b] * J[l][j][b]; h[b] += Ji[i][l][b] * Ji[j][l][b]; }
      LANES { GM[i * DIM + j][b] = g[b] / absdet[b]; KS[i][j][b] = h[b] * absdet[b]; }
    }
}

/* the facet permutations Pl[j] (q̂ in the local order = P q̂ in the global order) and the
   facet sizes |F_j| / |F̂| */
static inline void facets_lanes(const eq_ref *restrict r, const eq_table *restrict t,
                                const int64_t *cl, const double X[][LB], double Pl[][NF * NF][LB],
                                double size[][LB])
{
  for (int b = 0; b < LB; ++b)
    for (int j = 0; j < NV; ++j) {
      const double *P = r->P + facet_perm(r, t->gvert + cl[b] * NV, j) * NF * NF;
      for (int kl = 0; kl < NF * NF; ++kl) Pl[j][kl][b] = P[kl];
    }
  for (int j = 0; j < NV; ++j) {          /* |F_j| / |F̂| = sqrt(det(E Eᵀ)), as facet_size */
    int o[NV - 1], n = 0;
    for (int v = 0; v < NV; ++v) if (v != j) o[n++] = v;
    double E[DIM - 1][DIM][LB], G[DIM - 1][DIM - 1][LB];
    for (int a = 0; a < DIM - 1; ++a)
      for (int i = 0; i < DIM; ++i)
        LANES E[a][i][b] = X[o[a + 1] * DIM + i][b] - X[o[0] * DIM + i][b];
    for (int a = 0; a < DIM - 1; ++a)
      for (int c = 0; c < DIM - 1; ++c) {
        LANES G[a][c][b] = 0.0;
        for (int i = 0; i < DIM; ++i) LANES G[a][c][b] += E[a][i][b] * E[c][i][b];
      }
#if DIM == 2
    LANES size[j][b] = sqrt(fabs(G[0][0][b]));
#else
    LANES size[j][b] = sqrt(fabs(G[0][0][b] * G[1][1][b] - G[0][1][b] * G[1][0][b]));
#endif
  }
}

/* ∇̂û at the cell points */
static inline void gradient_lanes(const eq_ref *restrict r, const double Uc[][LB], double gu[][LB])
{
  for (int q = 0; q < NQ; ++q)
    for (int i = 0; i < DIM; ++i) {
      double v[LB] = {0.0};
      for (int u = 0; u < NU; ++u) LANES v[b] += Uc[u][b] * r->dphi[(q * NU + u) * DIM + i];
      LANES gu[q * DIM + i][b] = v[b];
    }
}

/* the reference divergence moments β_a = −s ∫ (ψ_a f − k∇u_h·∇ψ_a [+ ψ_a λ̃]) Q_j of
   each vertex's share */
static inline void divergence_lanes(const eq_ref *restrict r, const eq_table *restrict t,
                                    const int64_t *cl, const double gu[][LB],
                                    const double KS[][DIM][LB], const double *absdet,
                                    const double *s, const double K[][LB], const double F[][LB],
                                    double beta[][LB])
{
  double KSd[DIM * NV][LB], R0[NV * NP][LB] = {{0.0}};
  for (int i = 0; i < DIM; ++i)
    for (int a = 0; a < NV; ++a) {
      double v[LB] = {0.0};
      for (int k = 0; k < DIM; ++k) LANES v[b] += KS[i][k][b] * r->dlam[a * DIM + k];
      LANES KSd[i * NV + a][b] = v[b];
    }
  for (int q = 0; q < NQ; ++q) {
    const double *wl = r->wlamQ + q * NV * NP;
    for (int a = 0; a < NV; ++a) {
      double v[LB] = {0.0};
      for (int i = 0; i < DIM; ++i) LANES v[b] += gu[q * DIM + i][b] * KSd[i * NV + a][b];
      for (int j = 0; j < NP; ++j)
        LANES R0[a * NP + j][b] +=
            absdet[b] * F[q][b] * wl[a * NP + j] - v[b] * K[q][b] * r->wQ[q * NP + j];
    }
  }
  if (t->src)
    for (int aj = 0; aj < NV * NP; ++aj)
      LANES R0[aj][b] += absdet[b] * t->src[cl[b] * NV * NP + aj];
  for (int aj = 0; aj < NV * NP; ++aj) LANES beta[aj][b] = -s[b] * R0[aj][b];
}

/* the outward-flux data moments of each vertex's share, in the global facet bases:
   data[(j NV + a) NF + l] on facet j for vertex a */
static inline void data_lanes(const eq_ref *restrict r, const eq_table *restrict t,
                              const int64_t *cl, const double size[][LB],
                              const double Pl[][NF * NF][LB], double data[][LB])
{
  for (int j = 0; j < NV; ++j) {
    double factor[LB], loc[NV][NF][LB] = {{{0.0}}};  /* the moments in facet j's local basis */
    int any = 0;
    LANES {
      int kind = t->kind[cl[b] * NV + j];
      factor[b] = (kind == FLUX || kind == CONTACT) ? size[j][b] : 0.0;
      any |= kind == FLUX || kind == CONTACT;
    }
    if (any) {  /* a flux or contact facet in some lane: the moments of its data t */
      double Tq[NQF][LB];
      for (int q = 0; q < NQF; ++q) LANES Tq[q][b] = t->t[(cl[b] * NV + j) * NQF + q];
      for (int a = 0; a < NV; ++a)
        for (int k = 0; k < NF; ++k) {
          const double *bs = r->base + ((j * NV + a) * NF + k) * NQF;
          for (int q = 0; q < NQF; ++q) LANES loc[a][k][b] += bs[q] * Tq[q][b];
          LANES loc[a][k][b] *= factor[b];
        }
    }
    for (int a = 0; a < NV; ++a) {
      if (t->cidx)
        for (int b = 0; b < LB; ++b) {
          int64_t ci = t->cidx[cl[b]];
          if (ci >= 0 && t->kind[cl[b] * NV + j] == CONTACT)
            for (int k = 0; k < NF; ++k)
              loc[a][k][b] += size[j][b] * t->cmom[((ci * NV + j) * NV + a) * NF + k];
        }
      for (int l = 0; l < NF; ++l) {
        double v[LB] = {0.0};
        for (int k = 0; k < NF; ++k) LANES v[b] += Pl[j][k * NF + l][b] * loc[a][k][b];
        LANES data[(j * NV + a) * NF + l][b] = v[b];
      }
    }
  }
}

/* the load Zᵀg_a of each vertex a, g_a = ∫_T k_T⁻¹ ψ_a τ·φ (τ: k∇u_h, k∇(Σ Ut φ) or given) */
static inline void target_lanes(const eq_ref *restrict r, const eq_table *restrict t,
                                const int64_t *cl, const double J[][DIM][LB],
                                const double Ji[][DIM][LB], const double K[][LB],
                                const double Uc[][LB], const double gu[][LB], const double *kT,
                                const double *s, double ZTg[][LB])
{
  /* Zᵀg_a = s ∫ ψ̂_a lhs·(φ̂ Z), lhs = Jᵀτ / k_T: where k is one constant and τ = k∇ of a
     function of the element of u_h (u_h itself, or the coefficients Ut), lhs is the reference
     gradient of those coefficients and Zᵀg_a = s Σ_u c_u DZG_u (exact); else at the points,
     first over the components (y_q = lhs_q·(φ̂ Z)(x_q)), then over the points */
  memset(ZTg, 0, sizeof(double) * NV * MZ * LB);
  if (t->kstride == 0 && !t->tau && !LOWEST) {
    double Vc[NU][LB];
    if (t->Ut) for (int u = 0; u < NU; ++u) LANES Vc[u][b] = t->Ut[cl[b] * NU + u];
    else for (int u = 0; u < NU; ++u) LANES Vc[u][b] = Uc[u][b];
    for (int u = 0; u < NU; ++u) {
      const double *dz = r->DZG + u * NV * MZ;
      for (int az = 0; az < NV * MZ; ++az) LANES ZTg[az][b] += Vc[u][b] * dz[az];
    }
  } else {
    double lhs[NQ * DIM][LB];
    if (t->tau) {
      double TAU[NQ * DIM][LB];
#if LOWEST  /* one point per cell, the centroid: only the cell mean of τ enters */
      for (int qj = 0; qj < NQ * DIM; ++qj) LANES TAU[qj][b] = t->tau[cl[b] * DIM + qj % DIM];
#else
      for (int qj = 0; qj < NQ * DIM; ++qj) LANES TAU[qj][b] = t->tau[cl[b] * NQ * DIM + qj];
#endif
      for (int q = 0; q < NQ; ++q)
        for (int i = 0; i < DIM; ++i) {
          double v[LB] = {0.0};
          for (int j = 0; j < DIM; ++j) LANES v[b] += J[j][i][b] * TAU[q * DIM + j][b];
          LANES lhs[q * DIM + i][b] = v[b] / kT[b];
        }
    } else {
      for (int q = 0; q < NQ; ++q)
        for (int i = 0; i < DIM; ++i) {
          double v[LB] = {0.0};
          if (t->Ut)
            for (int u = 0; u < NU; ++u)
              LANES v[b] += t->Ut[cl[b] * NU + u] * r->dphi[(q * NU + u) * DIM + i];
          else LANES v[b] = gu[q * DIM + i][b];
          LANES lhs[q * DIM + i][b] = v[b] * K[q][b] / kT[b];
        }
    }
#if LOWEST
    /* the lowest-order flux of a P1 solution (Braess & Schöberl): the target is the RT_0
       interpolant of ψ_a w, w = J⁻ᵀ ŵ the cell mean of τ / k_T (ŵ = the mean of lhs),
       I(ψ_a w) = (w + (∇ψ_a·w)(x − x_a)) / d, so Zᵀg_a = s (ŵ·IZ + c_a Σ_ij (JᵀJ)_ij EZ_aij) / d
       with c_a = ∇ψ_a·w = ∇̂λ_aᵀ J⁻¹ J⁻ᵀ ŵ */
    double wh[DIM][LB] = {{0.0}}, JJ[DIM][DIM][LB], wp[DIM][LB];
    for (int q = 0; q < NQ; ++q)
      for (int i = 0; i < DIM; ++i) LANES wh[i][b] += r->w[q] * lhs[q * DIM + i][b] / r->wsum;
    for (int i = 0; i < DIM; ++i) {
      for (int j = 0; j < DIM; ++j) {
        LANES JJ[i][j][b] = 0.0;
        for (int l = 0; l < DIM; ++l) LANES JJ[i][j][b] += J[l][i][b] * J[l][j][b];
      }
      LANES wp[i][b] = 0.0;
      for (int l = 0; l < DIM; ++l) LANES wp[i][b] += Ji[l][i][b] * wh[l][b];  /* w = J⁻ᵀ ŵ */
    }
    for (int a = 0; a < NV; ++a) {
      double c[LB] = {0.0};
      for (int i = 0; i < DIM; ++i)
        for (int l = 0; l < DIM; ++l) LANES c[b] += r->dlam[a * DIM + l] * Ji[l][i][b] * wp[i][b];
      for (int z = 0; z < MZ; ++z) {
        double v[LB] = {0.0};
        for (int i = 0; i < DIM; ++i) {
          LANES v[b] += wh[i][b] * r->IZ[i * MZ + z];
          for (int j = 0; j < DIM; ++j)
            LANES v[b] += c[b] * JJ[i][j][b] * r->EZ[((a * DIM + i) * DIM + j) * MZ + z];
        }
        LANES ZTg[a * MZ + z][b] = v[b] / DIM;
      }
    }
#else
    (void)Ji;  /* only the lowest-order fit maps by J⁻¹ */
    for (int q = 0; q < NQ; ++q) {
      double y[MZ][LB] = {{0.0}};
      for (int i = 0; i < DIM; ++i) {
        const double *pz = r->phiZ + (q * DIM + i) * MZ;
        for (int z = 0; z < MZ; ++z) LANES y[z][b] += lhs[q * DIM + i][b] * pz[z];
      }
      for (int a = 0; a < NV; ++a) {
        double wl = r->wlam[q * NV + a];
        for (int z = 0; z < MZ; ++z) LANES ZTg[a * MZ + z][b] += wl * y[z][b];
      }
    }
#endif
  }
  for (int az = 0; az < NV * MZ; ++az) LANES ZTg[az][b] *= s[b];
}

/* the first of cell_block and flow_block: the cells cl of the lanes (the last cell fills the
   lanes past nb), their data (load_lanes) and geometry (geometry_lanes) */
#define CELL_LANES                                                                    \
  int64_t cl[LB];                                                                     \
  LANES cl[b] = cells[b < nb ? b : nb - 1];                                           \
  double X[NV * DIM][LB], K[NQ][LB], F[NQ][LB], Uc[NU][LB];                           \
  load_lanes(t, cl, X, K, F, Uc);                                                     \
  double J[DIM][DIM][LB], Ji[DIM][DIM][LB], det[LB], s[LB], absdet[LB];               \
  geometry_lanes(X, J, Ji, det, s, absdet)

/* The cell's part of the constant-flux step of the patch of its vertex a (solve_flow): over the
   outward fluxes Φ of the free spokes (facets j ≠ a not on Γ_N, Γ_C; those carry their data
   flux, the facet a none), min ½ΦᵀHΦ − gᵀΦ subject to ΣΦ = G' (the cell's divergence less
   the data fluxes) and the continuity multipliers μ of the interior spokes gives
   Φ = q − P μ, P = H⁻¹ − H⁻¹11ᵀH⁻¹ / 1ᵀH⁻¹1, q = P (g − f) + h G', h = H⁻¹1 / 1ᵀH⁻¹1
   (f: the data fluxes' part of the gradient), into fa (FA_* layout, spoke order; 0 for the
   data spokes).  Returns 1 if H is singular. */
static int flow_pair(const eq_ref *r, const int8_t *kind, int a, double G[NV][NV],
                     const double *g, double gb, const double *data, double *fa)
{
  int fr[DIM], nf = 0, slot[NV];
  double fixed[NV] = {0.0}, gp = gb;
  for (int j = 0, s1 = 0; j < NV; ++j) {
    if (j == a) continue;
    slot[j] = s1++;
    if (kind[j] == FLUX || kind[j] == CONTACT) {
      for (int l = 0; l < NF; ++l) fixed[j] += r->kappa[l] * data[(j * NV + a) * NF + l];
      gp -= fixed[j];
    } else {
      fr[nf++] = j;
    }
  }
  memset(fa, 0, sizeof(double) * FA_SIZE);
  fa[FA_G] = gp;
  if (nf == 0) return 0;
  double H[DIM * DIM], Hi[DIM * DIM], ge[DIM], v[DIM], c = 0.0;
  for (int x = 0; x < nf; ++x) {
    ge[x] = g[fr[x]];
    for (int k = 0; k < NV; ++k) ge[x] -= G[fr[x]][k] * fixed[k];
    for (int y = 0; y < nf; ++y) { H[x * nf + y] = G[fr[x]][fr[y]]; Hi[x * nf + y] = x == y; }
  }
  if (lu_solve(nf, H, Hi, nf)) return 1;
  for (int x = 0; x < nf; ++x) {
    v[x] = 0.0;
    for (int y = 0; y < nf; ++y) v[x] += Hi[x * nf + y];
    c += v[x];
  }
  double Pm[DIM * DIM];
  for (int x = 0; x < nf; ++x)
    for (int y = 0; y < nf; ++y) Pm[x * nf + y] = nf == 1 ? 0.0 : Hi[x * nf + y] - v[x] * v[y] / c;
  for (int x = 0; x < nf; ++x) {
    double q = v[x] / c * gp;
    for (int y = 0; y < nf; ++y) q += Pm[x * nf + y] * ge[y];
    fa[FA_Q + slot[fr[x]]] = q;
    fa[FA_H + slot[fr[x]]] = v[x] / c;
    fa[FA_F + slot[fr[x]]] = g[fr[x]] - ge[x];
    for (int y = 0; y < nf; ++y) fa[FA_P + slot[fr[x]] * DIM + slot[fr[y]]] = Pm[x * nf + y];
  }
  return 0;
}

/* The moment path (eq_flow): what the patches of the cells cells[0 .. nb) need, into rows[b]
   (FW_* layout): β_a and the data moments as cell_block's, and the cell's energy in its
   facet moments (A, b_a); osc_T as cell_block. */
static int flow_block(const eq_ref *restrict r, const eq_table *restrict t, const int64_t *cells,
                      int nb, double *const *rows, double *osc)
{
  CELL_LANES;
  double GM[DIM * DIM][LB], KS[DIM][DIM][LB];
  metric_lanes(J, Ji, absdet, GM, KS);
  double Pl[NV][NF * NF][LB], size[NV][LB];
  facets_lanes(r, t, cl, X, Pl, size);
  double gu[NQ * DIM][LB];
  gradient_lanes(r, Uc, gu);
  double beta[NV * NP][LB];
  divergence_lanes(r, t, cl, gu, KS, absdet, s, K, F, beta);
  double data[NV * NV * NF][LB];
  data_lanes(r, t, cl, size, Pl, data);
  double kT[LB] = {0.0};
  for (int q = 0; q < NQ; ++q) LANES kT[b] += K[q][b] * r->w[q];
  LANES kT[b] /= r->wsum;
  double ZTg[NV * MZ][LB];
  target_lanes(r, t, cl, J, Ji, K, Uc, gu, kT, s, ZTg);
  /* the cell mean τ̄ of the target (k∇u_h = k J⁻ᵀ ∇̂û, or τ) and τ̄·A_j, A_j = −(|det J| /
     (d − 1)!) J⁻ᵀ ∇̂λ_j the outward area vector of facet j: the moments ∫_F ψ_a τ̄·n q_l =
     τ̄·A_j Σ_k P_kl TB_jak start the higher moments */
  double tau[DIM][LB] = {{0.0}}, tA[NV][LB], fact1 = 1.0;
  for (int i = 2; i <= DIM - 1; ++i) fact1 *= i;
  if (t->tau) {
    for (int q = 0; q < NQ; ++q)
      for (int i = 0; i < DIM; ++i)
        LANES tau[i][b] += r->w[q] * t->tau[(cl[b] * NQ + q) * DIM + i];
  } else {
    double g[DIM][LB] = {{0.0}};
    for (int q = 0; q < NQ; ++q)
      for (int k = 0; k < DIM; ++k) LANES g[k][b] += r->w[q] * K[q][b] * gu[q * DIM + k][b];
    for (int i = 0; i < DIM; ++i)
      for (int k = 0; k < DIM; ++k) LANES tau[i][b] += Ji[k][i][b] * g[k][b];
  }
  for (int j = 0; j < NV; ++j) {
    double v[LB] = {0.0};
    for (int i = 0; i < DIM; ++i) {
      double gi[LB] = {0.0};
      for (int k = 0; k < DIM; ++k) LANES gi[b] += Ji[k][i][b] * r->dlam[j * DIM + k];
      LANES v[b] += tau[i][b] * gi[b];
    }
    LANES tA[j][b] = -absdet[b] / (fact1 * r->wsum) * v[b];
  }
  /* the energy ½‖σ − ψ_a τ‖²_{k_T⁻¹} in the reference facet moments m̂ of σ̂ = GL m̂ + RL β_a:
     ½ m̂ᵀ A m̂ − b_aᵀ m̂ + const, A = GLᵀ M GL, b_a = Gᵀ Zᵀg_a − GLᵀ M RL β_a, M = Σ GM_ij
     mass_ij / k_T (AR, BR: the reference GLᵀ mass_ij GL and GLᵀ mass_ij RL) */
  double A[DNF * DNF][LB], BT[DNF * NP][LB], bv[NV * DNF][LB];
  for (int x = 0; x < DNF; ++x)
    for (int y = 0; y <= x; ++y) {
      double v[LB] = {0.0};
      for (int ij = 0; ij < DIM * DIM; ++ij)
        LANES v[b] += GM[ij][b] * r->AR[(ij * DNF + x) * DNF + y];
      LANES A[x * DNF + y][b] = A[y * DNF + x][b] = v[b] / kT[b];
    }
  for (int xj = 0; xj < DNF * NP; ++xj) {
    double v[LB] = {0.0};
    for (int ij = 0; ij < DIM * DIM; ++ij) LANES v[b] += GM[ij][b] * r->BR[ij * DNF * NP + xj];
    LANES BT[xj][b] = v[b] / kT[b];
  }
  for (int a = 0; a < NV; ++a)
    for (int x = 0; x < DNF; ++x) {
      double v[LB] = {0.0};
      for (int z = 0; z < MZ; ++z) LANES v[b] += r->GT[x * MZ + z] * ZTg[a * MZ + z][b];
      for (int j = 0; j < NP; ++j) LANES v[b] -= BT[x * NP + j][b] * beta[a * NP + j][b];
      LANES bv[a * DNF + x][b] = v[b];
    }
  for (int b = 0; b < nb; ++b) {
    double *row = rows[b];
    for (int k = 0; k < NV * NP; ++k) row[k] = beta[k][b];
    for (int k = 0; k < NV * NV * NF; ++k) row[FW_DATA + k] = data[k][b];
    row[FW_S] = s[b];
    for (int j = 0; j < NV; ++j) row[FW_PERM + j] = facet_perm(r, t->gvert + cl[b] * NV, j);
    for (int k = 0; k < DNF * DNF; ++k) row[FW_AM + k] = A[k][b];
    for (int k = 0; k < NV * DNF; ++k) row[FW_B + k] = bv[k][b];
    for (int a = 0; a < NV; ++a)
      for (int j = 0; j < NV; ++j)
        for (int l = 0; l < NF; ++l) {
          double v = 0.0;
          for (int k = 0; k < NF; ++k) v += Pl[j][k * NF + l][b] * r->TB[(j * NV + a) * NF + k];
          row[FW_TM + (a * NV + j) * NF + l] = tA[j][b] * v;
        }
    osc[b] = oscillation(r, t, cl[b], absdet[b], size, b);
  }
  return 0;
}

/* The operators of the cells cells[0 .. nb) (operators.py), condensed per vertex (patches.py),
   into rows[b]: LB cells at a time, every operation a loop over the lanes b (the last cell
   fills the lanes nb .. LB - 1 and is not stored twice). */
static int cell_block(const eq_ref *restrict r, const eq_table *restrict t, const int64_t *cells,
                      int nb, double *const *rows, int64_t vlo, int64_t vhi, double *osc)
{
  CELL_LANES;
  double GM[DIM * DIM][LB], KS[DIM][DIM][LB], kT[LB] = {0.0};
  metric_lanes(J, Ji, absdet, GM, KS);
  for (int q = 0; q < NQ; ++q) LANES kT[b] += K[q][b] * r->w[q];
  LANES kT[b] /= r->wsum;
  /* M_Z = Zᵀ M Z, M_Z⁻¹ and Zᵀ M R (the weight k_T⁻¹) */
  double MZm[MZ * MZ * LB], MZi[MZ * MZ * LB], ZMR[MZ * NP][LB];
  for (int a = 0; a < MZ * MZ; ++a) {
    double v[LB] = {0.0};
    for (int ij = 0; ij < DIM * DIM; ++ij) LANES v[b] += GM[ij][b] * r->ZZ[ij * MZ * MZ + a];
    LANES MZm[a * LB + b] = v[b] / kT[b];
  }
  if (spd_inverse_lanes(MZ, MZm, MZi)) return 1;
  for (int a = 0; a < MZ * NP; ++a) {
    double v[LB] = {0.0};
    for (int ij = 0; ij < DIM * DIM; ++ij) LANES v[b] += GM[ij][b] * r->ZR[ij * MZ * NP + a];
    LANES ZMR[a][b] = v[b] / kT[b];
  }
  /* facet orientations and sizes; O Z and O R in the global facet bases */
  double Pl[NV][NF * NF][LB], size[NV][LB];
  facets_lanes(r, t, cl, X, Pl, size);
  double OZ[DNF * MZ][LB], OR[DNF * NP][LB];
  for (int j = 0; j < NV; ++j)
    for (int l = 0; l < NF; ++l) {
      for (int z = 0; z < MZ; ++z) {
        double v[LB] = {0.0};
        for (int k = 0; k < NF; ++k)
          LANES v[b] += Pl[j][k * NF + l][b] * r->NZ[(j * NF + k) * MZ + z];
        LANES OZ[(j * NF + l) * MZ + z][b] = s[b] * v[b];
      }
      for (int z = 0; z < NP; ++z) {
        double v[LB] = {0.0};
        for (int k = 0; k < NF; ++k)
          LANES v[b] += Pl[j][k * NF + l][b] * r->NR[(j * NF + k) * NP + z];
        LANES OR[(j * NF + l) * NP + z][b] = s[b] * v[b];
      }
    }
  /* Yt = (O Z) M_Z⁻¹, S = Yt (O Z)ᵀ */
  double Yt[DNF * MZ][LB], S[DNF * DNF][LB];
  for (int i = 0; i < DNF; ++i)
    for (int c = 0; c < MZ; ++c) {
      double v[LB] = {0.0};
      for (int a = 0; a < MZ; ++a) LANES v[b] += OZ[i * MZ + a][b] * MZi[(a * MZ + c) * LB + b];
      LANES Yt[i * MZ + c][b] = v[b];
    }
  for (int i = 0; i < DNF; ++i)
    for (int j = 0; j <= i; ++j) {
      double v[LB] = {0.0};
      for (int a = 0; a < MZ; ++a) LANES v[b] += Yt[i * MZ + a][b] * OZ[j * MZ + a][b];
      LANES S[i * DNF + j][b] = S[j * DNF + i][b] = v[b];
    }
  /* the data at the points: ∇̂û, the load Zᵀg_a and the divergence moments */
  double gu[NQ * DIM][LB];
  gradient_lanes(r, Uc, gu);
  double ZTg[NV * MZ][LB];
  target_lanes(r, t, cl, J, Ji, K, Uc, gu, kT, s, ZTg);
  double beta[NV * NP][LB];
  divergence_lanes(r, t, cl, gu, KS, absdet, s, K, F, beta);
  /* h_a = O R β_a + Yt (Zᵀg_a − ZMR β_a) */
  double h[NV * DNF][LB];
  for (int a = 0; a < NV; ++a) {
    double y[MZ][LB];
    for (int z = 0; z < MZ; ++z) {
      LANES y[z][b] = ZTg[a * MZ + z][b];
      for (int j = 0; j < NP; ++j) LANES y[z][b] -= ZMR[z * NP + j][b] * beta[a * NP + j][b];
    }
    for (int i = 0; i < DNF; ++i) {
      double v[LB] = {0.0};
      for (int j = 0; j < NP; ++j) LANES v[b] += OR[i * NP + j][b] * beta[a * NP + j][b];
      for (int z = 0; z < MZ; ++z) LANES v[b] += Yt[i * MZ + z][b] * y[z][b];
      LANES h[a * DNF + i][b] = v[b];
    }
  }
  /* outward-flux data of each vertex's share, in the global facet bases */
  double data[NV * NV * NF][LB];
  data_lanes(r, t, cl, size, Pl, data);
  /* condensation of the facet opposite each vertex a (patches.py):
     Ŝ_a = S_ss − T S_soᵀ, b_a = h_s − T h_o − data, T = S_so S_oo⁻¹; μ_o = S_oo⁻¹ h_o − Tᵀ μ_s */
  for (int a = 0; a < NV; ++a) {
    int Is[SNF], n = 0;
    for (int j = 0; j < NV; ++j) if (j != a) for (int k = 0; k < NF; ++k) Is[n++] = j * NF + k;
    double Soo[NF * NF * LB], Sooi[NF * NF * LB], T[SNF * NF][LB];
    for (int k = 0; k < NF; ++k)
      for (int l = 0; l < NF; ++l)
        LANES Soo[(k * NF + l) * LB + b] = S[(a * NF + k) * DNF + a * NF + l][b];
    if (spd_inverse_lanes(NF, Soo, Sooi)) return 1;
    for (int i = 0; i < SNF; ++i)
      for (int l = 0; l < NF; ++l) {
        double v[LB] = {0.0};
        for (int k = 0; k < NF; ++k)
          LANES v[b] += S[Is[i] * DNF + a * NF + k][b] * Sooi[(k * NF + l) * LB + b];
        LANES T[i * NF + l][b] = v[b];
      }
    double Sh[SNF * SNF][LB], bv[SNF][LB], ho[NF][LB];
    for (int i = 0; i < SNF; ++i) {
      for (int j = 0; j <= i; ++j) {
        double v[LB];
        LANES v[b] = S[Is[i] * DNF + Is[j]][b];
        for (int k = 0; k < NF; ++k)
          LANES v[b] -= T[i * NF + k][b] * S[Is[j] * DNF + a * NF + k][b];
        LANES Sh[i * SNF + j][b] = Sh[j * SNF + i][b] = v[b];
      }
      double v[LB];
      const double *dat = data[((Is[i] / NF) * NV + a) * NF + Is[i] % NF];
      LANES v[b] = h[a * DNF + Is[i]][b] - dat[b];
      for (int k = 0; k < NF; ++k) LANES v[b] -= T[i * NF + k][b] * h[a * DNF + a * NF + k][b];
      LANES bv[i][b] = v[b];
    }
    for (int k = 0; k < NF; ++k) {
      double v[LB] = {0.0};
      for (int l = 0; l < NF; ++l)
        LANES v[b] += Sooi[(k * NF + l) * LB + b] * h[a * DNF + a * NF + l][b];
      LANES ho[k][b] = v[b];
    }
    for (int b = 0; b < nb; ++b) {
      double *row = rows[b];
      double *sb = row + W_A(a);
      for (int i = 0, k = 0; i < SNF; ++i)
        for (int j = 0; j <= i; ++j) sb[k++] = Sh[i * SNF + j][b];
      for (int i = 0; i < SNF; ++i) sb[SYM + i] = bv[i][b];
      for (int k = 0; k < NF; ++k)
        for (int i = 0; i < SNF; ++i) sb[A_TA + k * SNF + i] = T[i * NF + k][b];
      for (int k = 0; k < NF; ++k) sb[A_HO + k] = ho[k][b];
    }
  }
  /* C = R Σ_a β_a + Z M_Z⁻¹ (Σ_a Zᵀg_a − ZMR Σ_a β_a) over the vertices solved here */
  double Bs[NP][LB] = {{0.0}}, Gs[MZ][LB] = {{0.0}}, gam[MZ][LB], own[NV][LB];
  for (int a = 0; a < NV; ++a)
    LANES { int64_t g = t->gvert[cl[b] * NV + a]; own[a][b] = g >= vlo && g < vhi; }
  for (int a = 0; a < NV; ++a) {
    for (int j = 0; j < NP; ++j) LANES Bs[j][b] += own[a][b] * beta[a * NP + j][b];
    for (int z = 0; z < MZ; ++z) LANES Gs[z][b] += own[a][b] * ZTg[a * MZ + z][b];
  }
  for (int z = 0; z < MZ; ++z)
    for (int j = 0; j < NP; ++j) LANES Gs[z][b] -= ZMR[z * NP + j][b] * Bs[j][b];
  for (int z = 0; z < MZ; ++z) {
    double v[LB] = {0.0};
    for (int y = 0; y < MZ; ++y) LANES v[b] += MZi[(z * MZ + y) * LB + b] * Gs[y][b];
    LANES gam[z][b] = v[b];
  }
  double C[M][LB];
  for (int l = 0; l < M; ++l) {
    LANES C[l][b] = 0.0;
    for (int j = 0; j < NP; ++j) LANES C[l][b] += r->R[l * NP + j] * Bs[j][b];
    for (int z = 0; z < MZ; ++z) LANES C[l][b] += r->Z[l * MZ + z] * gam[z][b];
  }
  for (int b = 0; b < nb; ++b) {
    for (int k = 0; k < DNF * MZ; ++k) rows[b][W_YT + k] = Yt[k][b];
    for (int l = 0; l < M; ++l) rows[b][W_C + l] = C[l][b];
  }
  for (int b = 0; b < nb; ++b) osc[b] = oscillation(r, t, cl[b], absdet[b], size, b);
  return 0;
}

/* osc_T of the rows the patches did not evaluate (osc NaN: cells none of whose vertices
   this rank solves) */
void eq_oscillation(const eq_ref *r, const eq_table *t, double *osc)
{
  for (int64_t c = 0; c < t->n; ++c) {
    if (osc[c] == osc[c]) continue;
    const double *x = t->x + c * NV * DIM;
    double J[DIM][DIM], Ji[DIM][DIM], size[NV][LB];
    for (int i = 0; i < DIM; ++i)
      for (int j = 0; j < DIM; ++j) J[i][j] = x[(j + 1) * DIM + i] - x[i];
    double absdet = fabs(det_inv(J, Ji));
    for (int j = 0; j < NV; ++j) size[j][0] = facet_size(x, j);
    osc[c] = oscillation(r, t, c, absdet, size, 0);
  }
}

/* ---------------------------------------------------------------------------------- */
/* patches                                                                              */
/* ---------------------------------------------------------------------------------- */
typedef struct {
  int64_t key[DIM - 1 > 0 ? DIM - 1 : 1];
  int kind;
} spoke_t;

static int key_cmp(const int64_t *a, const int64_t *b)
{
  for (int i = 0; i < DIM - 1; ++i) {
    if (a[i] < b[i]) return -1;
    if (a[i] > b[i]) return 1;
  }
  return 0;
}

typedef struct {
  int np, ns, nu, dim, maxdeg, maxraw, pure;
  int64_t *prow; int *ploc;       /* the pairs of the patch */
  int *spoke;                     /* (np, DIM): index of each pair's spoke in the sorted list */
  spoke_t *keys;                  /* the sorted unique spokes */
  int *order;                     /* scratch for sorting */
  spoke_t *raw;
  int *unknown;                   /* per spoke: position of its first dof / NF, or -1 */
  int *adj, *deg, *pos, *queue, *first;
  double *A, *rhs;
  const double *work;             /* the operators of the live cells, one row each */
  double *acc;                    /* per work row: Σ μ_a over its cell's pairs solved so far
                                     (eq_flow: Σ of the facet moments and β_a) */
  int64_t wsize;                  /* the doubles of a work row: W_SIZE, or FW_SIZE (eq_flow) */
  int sweeps;                     /* eq_flow: the rounds of (higher moments, constant fluxes) */
  double *fm, *fg, *ffa;          /* eq_flow, per pair: m̂, the energy's gradient, FA_* */
  double *fs;                     /* eq_flow, per spoke: 2 NH x NH (solve_flow) */
  int *fr1, *fr2, *fenv;          /* eq_flow, per spoke: its raw entries; the envelope */
  double *fmid;                   /* eq_flow, per spoke: its midpoint (times d) */
  const double *x;                /* the table's vertex coordinates */
  const int8_t *kind;             /* the table's facet kinds */
  const int64_t *slot;            /* table row -> its work row, or -1 */
  int *left;                      /* per work row: its cell's pairs not yet solved */
  int64_t *freel, nfree;          /* the work rows free for reuse */
  int *map;                       /* (np, DIM): the dof of each pair's spokes, or -1 */
  double *alpha, *defect;
  const eq_ref *r;
  struct batch_s **big;           /* per dim > DENSE: the open batch of that size, or NULL */
  double *P, *dinvl, *mu;         /* big batches: the packed lanes, 1 / L_ii, one lane's μ */
  int64_t Pcap, *off;
  int *fu;
} scratch_t;

#define CELL_WORK(w, c) ((w)->work + (w)->slot[c] * (w)->wsize)
/* the kind of facet j of pair p's cell; the facet of raw spoke entry x of a pair at vertex a */
#define FACET(x, a) ((x) % DIM < (a) ? (x) % DIM : (x) % DIM + 1)
#define t_kind(w, p, j) ((w)->kind[(w)->prow[p] * NV + (j)])
#define ACC_SIZE (DNF + NP)

/* the spokes of the patch: sorted unique keys (the facet's vertices other than a) */
static void spokes(const eq_table *t, scratch_t *w)
{
  int n = 0;
  for (int p = 0; p < w->np; ++p) {
    const int64_t *g = t->gvert + w->prow[p] * NV;
    int a = w->ploc[p];
    for (int j = 0; j < NV; ++j) {
      if (j == a) continue;
      int64_t o[DIM > 1 ? DIM - 1 : 1] = {0};
      int m = 0;
      for (int v = 0; v < NV; ++v) if (v != a && v != j) o[m++] = g[v];
      for (int x = 1; x < m; ++x)           /* sort the d - 1 others */
        for (int y = x; y > 0 && o[y - 1] > o[y]; --y)
          { int64_t s = o[y]; o[y] = o[y - 1]; o[y - 1] = s; }
      for (int x = 0; x < DIM - 1; ++x) w->raw[n].key[x] = o[x];
      w->raw[n].kind = t->kind[w->prow[p] * NV + j];
      w->order[n] = n;
      ++n;
    }
  }
  /* insertion sort of the indices by key */
  for (int x = 1; x < n; ++x) {
    int v = w->order[x], y = x;
    while (y > 0 && key_cmp(w->raw[w->order[y - 1]].key, w->raw[v].key) > 0) {
      w->order[y] = w->order[y - 1];
      --y;
    }
    w->order[y] = v;
  }
  int ns = 0;
  for (int x = 0; x < n; ++x) {
    int v = w->order[x];
    if (ns == 0 || key_cmp(w->keys[ns - 1].key, w->raw[v].key) != 0) w->keys[ns++] = w->raw[v];
    else w->keys[ns - 1].kind = w->raw[v].kind;
    w->spoke[v] = ns - 1;     /* raw index v = pair * DIM + s */
  }
  w->ns = ns;
}

/* reverse Cuthill-McKee order of the unknown spokes; pos[spoke] = its block position */
static void rcm(scratch_t *w)
{
  int ns = w->ns, md = w->maxdeg;
  for (int i = 0; i < ns; ++i) w->deg[i] = 0;
  int ok = 1;
  for (int p = 0; p < w->np; ++p)
    for (int s1 = 0; s1 < DIM; ++s1) {
      int u = w->spoke[p * DIM + s1];
      if (w->unknown[u] < 0) continue;
      for (int s2 = 0; s2 < DIM; ++s2) {
        int v = w->spoke[p * DIM + s2];
        if (s1 == s2 || w->unknown[v] < 0) continue;
        int seen = 0;
        for (int e = 0; e < w->deg[u]; ++e) seen |= w->adj[u * md + e] == v;
        if (!seen) { if (w->deg[u] < md) w->adj[u * md + w->deg[u]++] = v; else ok = 0; }
      }
    }
  int count = 0;
  for (int i = 0; i < ns; ++i) w->pos[i] = -1;
  if (!ok) {   /* more neighbours than a manifold patch has: keep the sorted order */
    for (int i = 0; i < ns; ++i) if (w->unknown[i] >= 0) w->pos[i] = count++;
    return;
  }
  int *queue = w->queue, head = 0, tail = 0;
  char *seen = (char *)w->first;   /* first[] is free here */
  for (int i = 0; i < ns; ++i) seen[i] = 0;
  for (;;) {
    int start = -1;
    for (int i = 0; i < ns; ++i)
      if (w->unknown[i] >= 0 && !seen[i] && (start < 0 || w->deg[i] < w->deg[start])) start = i;
    if (start < 0) break;
    seen[start] = 1;
    queue[tail++] = start;
    while (head < tail) {
      int u = queue[head++], lo = tail;
      for (int e = 0; e < w->deg[u]; ++e) {
        int v = w->adj[u * md + e];
        if (!seen[v]) { seen[v] = 1; queue[tail++] = v; }
      }
      for (int x = lo + 1; x < tail; ++x)      /* neighbours by increasing degree */
        for (int y = x; y > lo && w->deg[queue[y - 1]] > w->deg[queue[y]]; --y) {
          int s = queue[y]; queue[y] = queue[y - 1]; queue[y - 1] = s;
        }
    }
  }
  for (int x = 0; x < tail; ++x) w->pos[queue[x]] = tail - 1 - x;
}

/* the patch system: rhs and A (dense: the whole matrix; else its lower envelope) */
static void assemble(scratch_t *w, int dense)
{
  int dim = w->dim;
  double *A = w->A, *rhs = w->rhs;
  if (dense) memset(A, 0, sizeof(double) * dim * dim);
  else
    for (int i = 0; i < dim; ++i)
      memset(A + i * dim + w->first[i], 0, sizeof(double) * (i + 1 - w->first[i]));
  memset(rhs, 0, sizeof(double) * dim);
  for (int p = 0; p < w->np; ++p) {
    const double *Shat = CELL_WORK(w, w->prow[p]) + W_A(w->ploc[p]);
    const double *b = Shat + A_B;
    int row[SNF];
    for (int s1 = 0; s1 < DIM; ++s1) {
      int u = w->spoke[p * DIM + s1];
      for (int k = 0; k < NF; ++k) row[s1 * NF + k] = w->unknown[u] < 0 ? -1 : w->pos[u] * NF + k;
    }
    for (int i = 0; i < SNF; ++i) {
      if (row[i] < 0) continue;
      rhs[row[i]] += b[i];
      for (int j = 0; j < SNF; ++j)
        if (row[j] >= 0 && (dense || row[j] <= row[i]))
          A[row[i] * dim + row[j]] += Shat[SYMIDX(i, j)];
    }
  }
}

/* alpha[c] += C − Z Ytᵀ Σ_a μ_a */
static void finish_cell(const eq_ref *r, const double *cw, const double *msum, double *al)
{
  const double *Yt = cw + W_YT;
  double g[MZ] = {0.0};
  for (int i = 0; i < DNF; ++i)
    for (int z = 0; z < MZ; ++z) g[z] += Yt[i * MZ + z] * msum[i];
  for (int l = 0; l < M; ++l) {
    double v = cw[W_C + l];
    for (int z = 0; z < MZ; ++z) v -= r->Z[l * MZ + z] * g[z];
    al[l] += v;
  }
}

/* the pinned constant moment of a patch without a Dirichlet spoke: the largest constant
   moment of block position 0 */
static int pin_dof(const eq_ref *r)
{
  int pin = 0;
  for (int k = 0; k < NF; ++k) if (fabs(r->kappa[k]) > fabs(r->kappa[pin])) pin = k;
  return pin;
}

/* the dof of each pair's spokes in the patch system: map[p DIM + s] = pos NF, or -1 (Dirichlet) */
static void dof_map(scratch_t *w)
{
  for (int p = 0; p < w->np; ++p)
    for (int s1 = 0; s1 < DIM; ++s1) {
      int u = w->spoke[p * DIM + s1];
      w->map[p * DIM + s1] = w->unknown[u] < 0 ? -1 : w->pos[u] * NF;
    }
}

/* Number the unknown spokes (sorted order up to DENSE dofs, else reverse Cuthill-McKee and
   its envelope), assemble the patch system, project out the balance defect and pin one
   constant moment of a patch without a Dirichlet spoke (its kernel).  w->dim = 0: nothing to
   solve. */
static void setup_patch(const eq_ref *r, scratch_t *w, double *defect, int lanes)
{
  int nu = 0;
  w->pure = 1;
  for (int i = 0; i < w->ns; ++i) {
    w->pure &= w->keys[i].kind != DIRICHLET;
    w->unknown[i] = w->keys[i].kind == DIRICHLET ? -1 : nu++;
  }
  int dim = nu * NF;
  w->dim = dim;
  if (dim <= DENSE) {
    for (int i = 0; i < w->ns; ++i) w->pos[i] = w->unknown[i];
    for (int i = 0; i < dim; ++i) w->first[i] = 0;
  } else {
    rcm(w);
    for (int i = 0; i < dim; ++i) w->first[i] = (i / NF) * NF;
    for (int p = 0; p < w->np; ++p) {
      int lo = dim;
      for (int s1 = 0; s1 < DIM; ++s1) {
        int u = w->spoke[p * DIM + s1];
        if (w->unknown[u] >= 0 && w->pos[u] * NF < lo) lo = w->pos[u] * NF;
      }
      for (int s1 = 0; s1 < DIM; ++s1) {
        int u = w->spoke[p * DIM + s1];
        if (w->unknown[u] < 0) continue;
        for (int k = 0; k < NF; ++k) {
          int i = w->pos[u] * NF + k;
          if (lo < w->first[i]) w->first[i] = lo;
        }
      }
    }
  }
  dof_map(w);
  if (dim == 0) return;
  if (lanes && dim > DENSE) return;     /* flush_big assembles, projects and pins */
  assemble(w, 0);
  if (w->pure) {
    double kk = 0.0, bal = 0.0;
    int pin = pin_dof(r);
    for (int k = 0; k < NF; ++k) kk += r->kappa[k] * r->kappa[k];
    kk *= nu;
    for (int i = 0; i < dim; ++i) bal += w->rhs[i] * r->kappa[i % NF];
    *defect += fabs(bal) / kk * sqrt(kk);
    for (int i = 0; i < dim; ++i) w->rhs[i] -= bal / kk * r->kappa[i % NF];
    w->rhs[pin] = 0.0;
    for (int j = w->first[pin]; j < pin; ++j) w->A[pin * dim + j] = 0.0;
    for (int i = pin + 1; i < dim; ++i) if (w->first[i] <= pin) w->A[i * dim + pin] = 0.0;
    w->A[pin * dim + pin] = 1.0;
    w->rhs[pin] = 0.0;
  }
}

/* the pinned solution of a patch without a Dirichlet spoke, made orthogonal to the kernel */
static void project_kernel(const eq_ref *r, int dim, double *x)
{
  double kk = 0.0, c = 0.0;
  for (int i = 0; i < dim; ++i)
    { kk += r->kappa[i % NF] * r->kappa[i % NF]; c += x[i] * r->kappa[i % NF]; }
  for (int i = 0; i < dim; ++i) x[i] -= c / kk * r->kappa[i % NF];
}

/* the regularized dense system of patches.py, by LU (where the Cholesky met a non-positive
   pivot): the patch is set up anew in w (spokes() done) and solved into w->rhs */
static int regularized_solve(const eq_ref *r, scratch_t *w)
{
  double ignore = 0.0;
  setup_patch(r, w, &ignore, 0);
  int dim = w->dim;
  assemble(w, 1);
  if (w->pure) {
    double kk = 0.0, bal = 0.0, tr = 0.0;
    for (int i = 0; i < dim; ++i) kk += r->kappa[i % NF] * r->kappa[i % NF];
    for (int i = 0; i < dim; ++i) bal += w->rhs[i] * r->kappa[i % NF];
    for (int i = 0; i < dim; ++i)
      { w->rhs[i] -= bal / kk * r->kappa[i % NF]; tr += w->A[i * dim + i]; }
    double scale = tr / (dim * kk);
    for (int i = 0; i < dim; ++i)
      for (int j = 0; j < dim; ++j)
        w->A[i * dim + j] += scale * r->kappa[i % NF] * r->kappa[j % NF];
  }
  return lu_solve(dim, w->A, w->rhs, 1) ? 2 : 0;
}

/* μ of each pair from the patch solution mu (dofs by map), the opposite facet's from the
   condensation, summed into the cells' accumulators; a cell whose last pair this was is
   mapped to alpha (finish_cell) */
static void backsub(scratch_t *w, int np, const int64_t *prow, const int *ploc,
                    const int *map, const double *mu)
{
  for (int p = 0; p < np; ++p) {
    int64_t c = prow[p];
    int a = ploc[p];
    const double *cw = CELL_WORK(w, c);
    const double *Ta = cw + W_A(a) + A_TA, *ho = cw + W_A(a) + A_HO;
    double m[DNF], mus[SNF];
    for (int s1 = 0; s1 < DIM; ++s1) {
      int d0 = map[p * DIM + s1];
      for (int k = 0; k < NF; ++k) mus[s1 * NF + k] = d0 < 0 ? 0.0 : mu[d0 + k];
    }
    int n = 0;
    for (int j = 0; j < NV; ++j) if (j != a) for (int k = 0; k < NF; ++k) m[j * NF + k] = mus[n++];
    for (int k = 0; k < NF; ++k) {
      double v = ho[k];
      for (int i = 0; i < SNF; ++i) v -= Ta[k * SNF + i] * mus[i];
      m[a * NF + k] = v;
    }
    /* σ_h|_T is linear in Σ_a μ_a: sum, and map once per cell (finish_cell) */
    int64_t i = w->slot[c];
    double *acc = w->acc + i * ACC_SIZE;
    for (int k = 0; k < DNF; ++k) acc[k] += m[k];
    if (--w->left[i] == 0) {
      finish_cell(w->r, cw, acc, w->alpha + c * M);
      w->freel[w->nfree++] = i;
    }
  }
}

/* eq_flow: σ_h|_T += Σ_a σ_a|_T from the summed reference facet moments m̂ and divergence
   moments β of the cell: σ̂ = GL m̂ + RL β (GL = Z G, RL = R̂ − Z G N̂R̂, G a left inverse of
   N̂Z: for p = 1 the moments determine σ̂) */
static void finish_flow(const eq_ref *r, const double *acc, double *al)
{
  for (int l = 0; l < M; ++l) {
    double v = 0.0;
    for (int i = 0; i < DNF; ++i) v += r->GL[l * DNF + i] * acc[i];
    for (int j = 0; j < NP; ++j) v += r->RL[l * NP + j] * acc[DNF + j];
    al[l] += v;
  }
}

/* m̂_F of the cell on the other side of the spoke from m̂ of this side, higher moments only:
   m̂' = −s s' P' Pᵀ m̂ (the outward moments are opposite; P = diag(1, P_h)) */
static void across(const eq_ref *r, const double *cw, int j, const double *co, int jo,
                   const double *hi, double *out)
{
  const double *P = r->P + (int)cw[FW_PERM + j] * NF * NF;
  const double *Po = r->P + (int)co[FW_PERM + jo] * NF * NF;
  double sg = -cw[FW_S] * co[FW_S], glob[NF];
  for (int l = 1; l < NF; ++l) {
    glob[l] = 0.0;
    for (int k = 1; k < NF; ++k) glob[l] += P[k * NF + l] * hi[k - 1];
  }
  for (int k = 1; k < NF; ++k) {
    double v = 0.0;
    for (int l = 1; l < NF; ++l) v += Po[k * NF + l] * glob[l];
    out[k - 1] = sg * v;
  }
}

/* a before b in the lexicographic order of points */
static int before(const double *a, const double *b)
{
  for (int i = 0; i < DIM; ++i)
    if (a[i] != b[i]) return a[i] < b[i];
  return 0;
}

/* m̂_j += dm at the moments idx[0 .. n) of facet j, the gradient g += A[:, those] dm */
static void move(const double *cw, double *mh, double *g, int j, const int *idx, int n,
                 const double *dm)
{
  const double *A = cw + FW_AM;
  for (int x = 0; x < n; ++x) {
    int c = j * NF + idx[x];
    mh[c] += dm[x];
    for (int y = 0; y < DNF; ++y) g[y] += A[y * DNF + c] * dm[x];
  }
}

/* The patch of w (spokes() done) in the reference facet moments m̂ of σ_a on each pair's cell
   (σ̂_a = GL m̂ + RL β_a; the facet opposite a: 0; Γ_N, Γ_C: the data), minimizing the patch's
   Σ_T ½‖σ_a − ψ_a τ‖²_{k_T⁻¹} = Σ_T ½ m̂ᵀA_T m̂ − b_aᵀ m̂ (+ const) by block coordinate
   descent from m̂ = 0: (1) the constant outward fluxes Φ of the free spokes, over which the
   constraints act (the balance of every cell and continuity): with each cell's part
   Φ = q − P μ (flow_pair), the multipliers μ of the interior spokes solve Σ_T P_T μ = Σ_T q_T
   (a patch without a Dirichlet spoke: its balance defect is shared out over its cells first
   and one μ pinned); (2) the higher moments of each free spoke in turn (unconstrained: the
   two cells' energy minimized over them, a (NF − 1)-square system); then w->sweeps rounds of
   (2), (1).  Every iterate after the first (1) is admissible; the rounds only bring it
   closer to the patch minimizer of :mod:`.patches`.  Each pair's m̂ and β_a are summed into
   its cell's accumulator, mapped to alpha after the cell's last pair (finish_flow). */
static int solve_flow(const eq_ref *r, scratch_t *w, double *defect)
{
  int np = w->np, ns = w->ns, pure = 1, ni = 0, hidx[NH], zero = 0;
  int *r1 = w->fr1, *r2 = w->fr2, *idx = w->pos, *fe = w->fenv;  /* raw entries, dof, envelope */
  double *S = w->A, *mu = w->rhs, *dinv = w->dinvl, bal = 0.0, k0 = r->kappa[0];
  for (int l = 1; l < NF; ++l) hidx[l - 1] = l;
  for (int u = 0; u < ns; ++u) r1[u] = r2[u] = -1;
  for (int x = 0; x < np * DIM; ++x) {
    int u = w->spoke[x];
    if (r1[u] < 0) r1[u] = x; else r2[u] = x;
  }
  for (int u = 0; u < ns; ++u) {           /* the interior spokes, by reverse Cuthill-McKee */
    pure &= w->keys[u].kind != DIRICHLET;
    w->unknown[u] = w->keys[u].kind == INTERIOR && r2[u] >= 0 ? ni++ : -1;
  }
  rcm(w);
  for (int i = 0; i < ni; ++i) fe[i] = i;
  for (int p = 0; p < np; ++p) {
    int lo = ni;
    for (int s1 = 0; s1 < DIM; ++s1) {
      int i = idx[w->spoke[p * DIM + s1]];
      if (i >= 0 && i < lo) lo = i;
    }
    for (int s1 = 0; s1 < DIM; ++s1) {
      int i = idx[w->spoke[p * DIM + s1]];
      if (i >= 0 && lo < fe[i]) fe[i] = lo;
    }
  }
  /* m̂ = the data on Γ_N, Γ_C spokes, else 0; the gradient A m̂ − b_a */
  for (int p = 0; p < np; ++p) {
    const double *cw = CELL_WORK(w, w->prow[p]);
    int a = w->ploc[p];
    double *mh = w->fm + p * DNF, *g = w->fg + p * DNF;
    memset(mh, 0, sizeof(double) * DNF);
    for (int y = 0; y < DNF; ++y) g[y] = -cw[FW_B + a * DNF + y];
    for (int j = 0; j < NV; ++j) {
      int kind = t_kind(w, p, j);
      if (j == a || (kind != FLUX && kind != CONTACT)) continue;
      const double *P = r->P + (int)cw[FW_PERM + j] * NF * NF;
      double dm[NF];
      for (int k = 0; k < NF; ++k) {
        dm[k] = 0.0;
        for (int l = 0; l < NF; ++l) dm[k] += P[k * NF + l] * cw[FW_DATA + (j * NV + a) * NF + l];
        dm[k] *= cw[FW_S];
      }
      int all[NF];
      for (int k = 0; k < NF; ++k) all[k] = k;
      move(cw, mh, g, j, all, NF, dm);
    }
  }
  /* the higher moments of the free spokes start at the mean of the two cells' ψ_a τ̄ (Γ_D: the
     one cell's): the fit of σ_a to ψ_a τ is then O(h) from the first round */
  if (NF > 1)
    for (int u = 0; u < ns; ++u) {
      int kind = w->keys[u].kind;
      if (kind == FLUX || kind == CONTACT) continue;
      int xs[2] = {r1[u], r2[u]};
      double glob[NF];
      for (int side = 0; side < 2; ++side) {
        if (xs[side] < 0) continue;
        int p = xs[side] / DIM, a = w->ploc[p], j = FACET(xs[side], a);
        const double *cw = CELL_WORK(w, w->prow[p]), *own = cw + FW_TM + (a * NV + j) * NF;
        if (side == 0)
          for (int l = 0; l < NF; ++l) glob[l] = own[l];
        if (xs[1] >= 0) {             /* ½ (own − other), outward from each side */
          int po = xs[1 - side] / DIM, ao = w->ploc[po];
          int jo = FACET(xs[1 - side], ao);
          const double *oth = CELL_WORK(w, w->prow[po]) + FW_TM + (ao * NV + jo) * NF;
          for (int l = 0; l < NF; ++l) glob[l] = 0.5 * (own[l] - oth[l]);
        }
        const double *P = r->P + (int)cw[FW_PERM + j] * NF * NF;
        double dm[NH];
        for (int k = 1; k < NF; ++k) {
          double v = 0.0;
          for (int l = 1; l < NF; ++l) v += P[k * NF + l] * glob[l];
          dm[k - 1] = cw[FW_S] * v;
        }
        move(cw, w->fm + p * DNF, w->fg + p * DNF, j, hidx, NH, dm);
      }
    }
  /* the spokes in the order of their midpoints (x, then y, then z): the sweeps of (2), and so
     σ_h, do not depend on the vertex numbering (another partition, another numbering) */
  int *order = w->order;
  double *mid = w->fmid;
  for (int u = 0; u < ns; ++u) {
    int x1 = r1[u], p1 = x1 / DIM, j1 = FACET(x1, w->ploc[p1]);
    const double *xc = w->x + w->prow[p1] * NV * DIM;
    for (int i = 0; i < DIM; ++i) {
      mid[u * DIM + i] = 0.0;
      for (int v = 0; v < NV; ++v) if (v != j1) mid[u * DIM + i] += xc[v * DIM + i];
    }
    int y = u;
    for (; y > 0 && before(mid + u * DIM, mid + order[y - 1] * DIM); --y) order[y] = order[y - 1];
    order[y] = u;
  }
  int factored = 0;
  for (int round = 0; round <= w->sweeps; ++round) {
    if (round > 0 && NF > 1) {           /* (2) the higher moments, spoke by spoke */
      for (int o = 0; o < ns; ++o) {
        int u = order[o], kind = w->keys[u].kind;
        if (kind == FLUX || kind == CONTACT) continue;
        /* per spoke (first round; kept): Hi = (A_1 + Qᵀ A_2 Q)⁻¹ over the higher moments and
           Q (column x: across(e_x)) */
        double *Hi = w->fs + u * 2 * NH * NH, *Q = Hi + NH * NH;
        int x1 = r1[u], p1 = x1 / DIM, a1 = w->ploc[p1];
        int j1 = FACET(x1, a1), p2 = -1, j2 = 0;
        const double *c1 = CELL_WORK(w, w->prow[p1]), *c2 = NULL;
        if (r2[u] >= 0) {
          int x2 = r2[u], a2;
          p2 = x2 / DIM;
          a2 = w->ploc[p2];
          j2 = FACET(x2, a2);
          c2 = CELL_WORK(w, w->prow[p2]);
        }
        if (round == 1) {
          const double *A1 = c1 + FW_AM;
          double H[NH * NH];
          for (int x = 0; x < NH; ++x)
            for (int y = 0; y < NH; ++y) {
              H[x * NH + y] = A1[(j1 * NF + x + 1) * DNF + j1 * NF + y + 1];
              Hi[x * NH + y] = x == y;
            }
          if (p2 >= 0) {
            const double *A2 = c2 + FW_AM;
            for (int x = 0; x < NH; ++x) {
              double e[NH];
              for (int y = 0; y < NH; ++y) e[y] = x == y;
              across(r, c1, j1, c2, j2, e, Q + x * NH);
            }
            for (int x = 0; x < NH; ++x)
              for (int y = 0; y < NH; ++y)
                for (int k = 0; k < NH; ++k)
                  for (int l = 0; l < NH; ++l)
                    H[x * NH + y] += Q[x * NH + k] * A2[(j2 * NF + k + 1) * DNF + j2 * NF + l + 1]
                                     * Q[y * NH + l];
          }
          if (lu_solve(NH, H, Hi, NH)) return 2;
        }
        double rhs[NH], dz[NH], dz2[NH];
        for (int x = 0; x < NH; ++x) {
          rhs[x] = -w->fg[p1 * DNF + j1 * NF + x + 1];
          if (p2 >= 0)
            for (int y = 0; y < NH; ++y)
              rhs[x] -= Q[x * NH + y] * w->fg[p2 * DNF + j2 * NF + y + 1];
        }
        for (int x = 0; x < NH; ++x) {
          dz[x] = 0.0;
          for (int y = 0; y < NH; ++y) dz[x] += Hi[x * NH + y] * rhs[y];
        }
        move(c1, w->fm + p1 * DNF, w->fg + p1 * DNF, j1, hidx, NH, dz);
        if (p2 >= 0) {
          for (int y = 0; y < NH; ++y) {
            dz2[y] = 0.0;
            for (int x = 0; x < NH; ++x) dz2[y] += Q[x * NH + y] * dz[x];
          }
          move(c2, w->fm + p2 * DNF, w->fg + p2 * DNF, j2, hidx, NH, dz2);
        }
      }
    }
    /* (1) the constant fluxes: each cell's part (flow_pair), the spoke system, Φ */
    for (int p = 0; p < np; ++p) {
      const double *cw = CELL_WORK(w, w->prow[p]), *A = cw + FW_AM;
      int a = w->ploc[p];
      double G[NV][NV], g[NV], gb = 0.0, sg = cw[FW_S], *mh = w->fm + p * DNF;
      for (int i = 0; i < NV; ++i) {   /* the energy in Φ: m̂_j[0] = s Φ_j / κ_0 */
        g[i] = w->fg[p * DNF + i * NF];
        for (int j = 0; j < NV; ++j) {
          G[i][j] = A[i * NF * DNF + j * NF] / (k0 * k0);
          g[i] -= A[i * NF * DNF + j * NF] * mh[j * NF];
        }
        g[i] *= -sg / k0;
      }
      for (int j = 0; j < NP; ++j) gb += cw[a * NP + j] * r->qint[j];
      double *fa = w->ffa + p * FA_SIZE;
      if (round == 0) {
        int8_t kinds[NV];
        for (int j = 0; j < NV; ++j) kinds[j] = t_kind(w, p, j);
        if (flow_pair(r, kinds, a, G, g, sg * gb, cw + FW_DATA, fa)) return 1;
        bal += fa[FA_G];
      } else {                          /* the same H: q = P (g − f) + h G' */
        double ge[DIM];
        for (int s1 = 0; s1 < DIM; ++s1) ge[s1] = g[s1 < a ? s1 : s1 + 1] - fa[FA_F + s1];
        for (int s1 = 0; s1 < DIM; ++s1) {
          double q = fa[FA_H + s1] * fa[FA_G];
          for (int s2 = 0; s2 < DIM; ++s2) q += fa[FA_P + s1 * DIM + s2] * ge[s2];
          fa[FA_Q + s1] = q;
        }
      }
    }
    if (round == 0 && pure) *defect += fabs(bal);
    double delta = pure ? -bal / np : 0.0;
    if (!factored)
      for (int i = 0; i < ni; ++i) memset(S + i * ni + fe[i], 0, sizeof(double) * (i + 1 - fe[i]));
    memset(mu, 0, sizeof(double) * ni);
    for (int p = 0; p < np; ++p) {
      const double *fa = w->ffa + p * FA_SIZE;
      for (int s1 = 0; s1 < DIM; ++s1) {
        int i1 = idx[w->spoke[p * DIM + s1]];
        if (i1 < 0) continue;
        mu[i1] += fa[FA_Q + s1] + fa[FA_H + s1] * delta;
        if (factored) continue;
        for (int s2 = 0; s2 < DIM; ++s2) {
          int i2 = idx[w->spoke[p * DIM + s2]];
          if (i2 >= 0 && i2 <= i1) S[i1 * ni + i2] += fa[FA_P + s1 * DIM + s2];
        }
      }
    }
    if (!factored) {
      for (int i = 0; i < ni; ++i)      /* a spoke between two cells with one free flux each */
        if (S[i * ni + i] == 0.0) S[i * ni + i] = 1.0;
      if (pure && ni) {
        for (int i = 0; i < ni; ++i) if (fe[i] == 0) S[i * ni] = 0.0;
        S[0] = 1.0;
      }
      for (int i = 0; i < ni; ++i) {        /* Cholesky in the envelope, lower triangle */
        double *Si = S + i * ni;
        for (int j = fe[i]; j < i; ++j) {
          const double *Sj = S + j * ni;
          double v = Si[j];
          for (int k = fe[i] > fe[j] ? fe[i] : fe[j]; k < j; ++k) v -= Si[k] * Sj[k];
          Si[j] = v * dinv[j];
        }
        double v = Si[i];
        for (int k = fe[i]; k < i; ++k) v -= Si[k] * Si[k];
        if (!(v > 0.0)) return 2;
        dinv[i] = 1.0 / sqrt(v);
      }
      factored = 1;
    }
    if (pure && ni) mu[0] = 0.0;
    for (int i = 0; i < ni; ++i) {
      double v = mu[i];
      for (int k = fe[i]; k < i; ++k) v -= S[i * ni + k] * mu[k];
      mu[i] = v * dinv[i];
    }
    for (int i = ni - 1; i >= 0; --i) {
      mu[i] *= dinv[i];
      for (int k = fe[i]; k < i; ++k) mu[k] -= S[i * ni + k] * mu[i];
    }
    for (int p = 0; p < np; ++p) {
      const double *cw = CELL_WORK(w, w->prow[p]), *fa = w->ffa + p * FA_SIZE;
      int a = w->ploc[p];
      for (int s1 = 0; s1 < DIM; ++s1) {
        int kind = w->keys[w->spoke[p * DIM + s1]].kind, j = s1 < a ? s1 : s1 + 1;
        if (kind == FLUX || kind == CONTACT) continue;
        double phi = fa[FA_Q + s1] + fa[FA_H + s1] * delta;
        for (int s2 = 0; s2 < DIM; ++s2) {
          int i2 = idx[w->spoke[p * DIM + s2]];
          if (i2 >= 0) phi -= fa[FA_P + s1 * DIM + s2] * mu[i2];
        }
        double dm = cw[FW_S] * phi / k0 - w->fm[p * DNF + j * NF];
        move(cw, w->fm + p * DNF, w->fg + p * DNF, j, &zero, 1, &dm);
      }
    }
  }
  for (int p = 0; p < np; ++p) {
    int64_t c = w->prow[p];
    const double *cw = CELL_WORK(w, c);
    int a = w->ploc[p];
    int64_t i = w->slot[c];
    double *acc = w->acc + i * ACC_SIZE;
    for (int k = 0; k < DNF; ++k) acc[k] += w->fm[p * DNF + k];
    for (int j = 0; j < NP; ++j) acc[DNF + j] += cw[a * NP + j];
    if (--w->left[i] == 0) {
      finish_flow(r, acc, w->alpha + c * M);
      w->freel[w->nfree++] = i;
    }
  }
  return 0;
}

/* Patch systems are factorized LB at a time (the lanes of one size): the Cholesky of a
   small system is a chain of dependent divisions and square roots, which the lanes overlap,
   and the inner products of a big one are vector operations across the lanes.  Systems of
   DENSE dofs or fewer are dense; bigger ones keep the union of the lanes' envelopes. */
typedef struct batch_s {
  int count, np[LB], pure[LB];
  const int64_t *prow[LB];
  const int *ploc[LB];
  int *map;                /* (LB, maxraw) */
  int *first;              /* big: (LB, dim) the envelope of each lane */
  double *A, *x;           /* small: [(i dim + j) LB + b]; [i LB + b] */
} batch_t;

/* μ of each lane from x (a lane whose Cholesky met a non-positive pivot: the regularized
   system by LU), mapped back to its cells */
static int finish_lanes(const eq_ref *r, const eq_table *t, scratch_t *w, batch_t *bt, int dim,
                        const double *x, const int *bad)
{
  int nraw = w->maxraw;
  double *mu = w->mu;
  for (int b = 0; b < bt->count; ++b) {
    const int *map = bt->map + b * nraw;
    if (bad[b]) {
      w->np = bt->np[b];
      w->prow = (int64_t *)bt->prow[b];
      w->ploc = (int *)bt->ploc[b];
      spokes(t, w);
      if (regularized_solve(r, w)) return 2;
      memcpy(mu, w->rhs, sizeof(double) * dim);
      map = w->map;
    } else {
      for (int i = 0; i < dim; ++i) mu[i] = x[i * LB + b];
      if (bt->pure[b]) project_kernel(r, dim, mu);
    }
    backsub(w, bt->np[b], bt->prow[b], bt->ploc[b], map, mu);
  }
  bt->count = 0;
  return 0;
}

static int flush(const eq_ref *r, const eq_table *t, scratch_t *w, batch_t *bt, int dim)
{
  if (bt->count == 0) return 0;
  double *A = bt->A, *x = bt->x, dinv[DENSE][LB];
  int bad[LB] = {0};
  for (int i = 0; i < dim; ++i) {
    for (int j = 0; j < i; ++j) {
      double v[LB];
      LANES v[b] = A[(i * dim + j) * LB + b];
      for (int k = 0; k < j; ++k)
        LANES v[b] -= A[(i * dim + k) * LB + b] * A[(j * dim + k) * LB + b];
      LANES A[(i * dim + j) * LB + b] = v[b] * dinv[j][b];
    }
    double v[LB];
    LANES v[b] = A[(i * dim + i) * LB + b];
    for (int k = 0; k < i; ++k) LANES v[b] -= A[(i * dim + k) * LB + b] * A[(i * dim + k) * LB + b];
    LANES { if (!(v[b] > 0.0)) { bad[b] = 1; v[b] = 1.0; } dinv[i][b] = 1.0 / sqrt(v[b]); }
  }
  for (int i = 0; i < dim; ++i) {
    double v[LB];
    LANES v[b] = x[i * LB + b];
    for (int k = 0; k < i; ++k) LANES v[b] -= A[(i * dim + k) * LB + b] * x[k * LB + b];
    LANES x[i * LB + b] = v[b] * dinv[i][b];
  }
  for (int i = dim - 1; i >= 0; --i) {
    LANES x[i * LB + b] *= dinv[i][b];
    for (int k = 0; k < i; ++k) LANES x[k * LB + b] -= A[(i * dim + k) * LB + b] * x[i * LB + b];
  }
  for (int b = bt->count; b < LB; ++b) bad[b] = 0;
  return finish_lanes(r, t, w, bt, dim, x, bad);
}

/* Σ_{k0 <= k < j} a[k LB + b] c[k LB + b] subtracted from v, two partial sums per lane */
static inline void lanes_dot(double *restrict v, const double *restrict a,
                             const double *restrict c, int k0, int j)
{
  double v1[LB] = {0.0};
  int k = k0;
  for (; k + 1 < j; k += 2)
    LANES {
      v[b] -= a[k * LB + b] * c[k * LB + b];
      v1[b] -= a[(k + 1) * LB + b] * c[(k + 1) * LB + b];
    }
  if (k < j) LANES v[b] -= a[k * LB + b] * c[k * LB + b];
  LANES v[b] += v1[b];
}

/* A big batch: the lanes' systems assembled into the union of their envelopes (entry (i, j),
   fu[i] <= j <= i, of lane b at P[(off[i] + j − fu[i]) LB + b]; lanes past count are the
   identity), pinned where pure (setup_patch), factorized by Cholesky and solved */
static int flush_big(const eq_ref *r, const eq_table *t, scratch_t *w, batch_t *bt, int dim)
{
  int n = bt->count, *fu = w->fu;
  if (n == 0) return 0;
  int64_t *off = w->off;
  for (int i = 0; i < dim; ++i) {
    int f = i;
    for (int b = 0; b < n; ++b) if (bt->first[b * dim + i] < f) f = bt->first[b * dim + i];
    fu[i] = f;
  }
  off[0] = 0;
  for (int i = 0; i < dim; ++i) off[i + 1] = off[i] + (i + 1 - fu[i]);
  if (off[dim] > w->Pcap) {
    double *P = realloc(w->P, sizeof(double) * off[dim] * LB);
    if (!P) return 3;
    w->P = P;
    w->Pcap = off[dim];
  }
  double *P = w->P, *x = bt->x, *dinv = w->dinvl;
  memset(P, 0, sizeof(double) * off[dim] * LB);
  memset(x, 0, sizeof(double) * dim * LB);
  for (int b = 0; b < LB; ++b) {
    if (b >= n) {
      for (int i = 0; i < dim; ++i) P[(off[i] + i - fu[i]) * LB + b] = 1.0;
      continue;
    }
    const int *map = bt->map + b * w->maxraw;
    for (int p = 0; p < bt->np[b]; ++p) {
      const double *Shat = CELL_WORK(w, bt->prow[b][p]) + W_A(bt->ploc[b][p]);
      int row[SNF];
      for (int s1 = 0; s1 < DIM; ++s1) {
        int d0 = map[p * DIM + s1];
        for (int k = 0; k < NF; ++k) row[s1 * NF + k] = d0 < 0 ? -1 : d0 + k;
      }
      for (int i = 0; i < SNF; ++i) {
        int ri = row[i];
        if (ri < 0) continue;
        x[ri * LB + b] += Shat[A_B + i];
        double *Pi = P + (off[ri] - fu[ri]) * LB + b;
        for (int j = 0; j < SNF; ++j)
          if (row[j] >= 0 && row[j] <= ri) Pi[row[j] * LB] += Shat[SYMIDX(i, j)];
      }
    }
    if (bt->pure[b]) {           /* setup_patch: the balance defect, the pinned moment */
      int pin = pin_dof(r);
      double kk = 0.0, bal = 0.0;
      for (int k = 0; k < NF; ++k) kk += r->kappa[k] * r->kappa[k];
      kk *= dim / NF;
      for (int i = 0; i < dim; ++i) bal += x[i * LB + b] * r->kappa[i % NF];
      *w->defect += fabs(bal) / kk * sqrt(kk);
      for (int i = 0; i < dim; ++i) x[i * LB + b] -= bal / kk * r->kappa[i % NF];
      x[pin * LB + b] = 0.0;
      for (int j = fu[pin]; j < pin; ++j) P[(off[pin] + j - fu[pin]) * LB + b] = 0.0;
      for (int i = pin + 1; i < dim; ++i)
        if (fu[i] <= pin) P[(off[i] + pin - fu[i]) * LB + b] = 0.0;
      P[(off[pin] + pin - fu[pin]) * LB + b] = 1.0;
    }
  }
  int bad[LB] = {0};
  for (int i = 0; i < dim; ++i) {
    double *Pi = P + (off[i] - fu[i]) * LB;          /* Pi[j LB + b]: entry (i, j) */
    for (int j = fu[i]; j < i; ++j) {
      const double *Pj = P + (off[j] - fu[j]) * LB;
      double v[LB];
      LANES v[b] = Pi[j * LB + b];
      lanes_dot(v, Pi, Pj, fu[i] > fu[j] ? fu[i] : fu[j], j);
      LANES Pi[j * LB + b] = v[b] * dinv[j * LB + b];
    }
    double v[LB];
    LANES v[b] = Pi[i * LB + b];
    lanes_dot(v, Pi, Pi, fu[i], i);
    LANES {
      if (!(v[b] > 0.0)) { bad[b] = 1; v[b] = 1.0; }
      dinv[i * LB + b] = 1.0 / sqrt(v[b]);
    }
  }
  for (int i = 0; i < dim; ++i) {
    const double *Pi = P + (off[i] - fu[i]) * LB;
    double v[LB];
    LANES v[b] = x[i * LB + b];
    lanes_dot(v, Pi, x, fu[i], i);
    LANES x[i * LB + b] = v[b] * dinv[i * LB + b];
  }
  for (int i = dim - 1; i >= 0; --i) {
    const double *Pi = P + (off[i] - fu[i]) * LB;
    LANES x[i * LB + b] *= dinv[i * LB + b];
    for (int k = fu[i]; k < i; ++k) LANES x[k * LB + b] -= Pi[k * LB + b] * x[i * LB + b];
  }
  return finish_lanes(r, t, w, bt, dim, x, bad);
}

/* the open batch of big systems of size dim (made at first use), or NULL: out of memory */
static batch_t *big_batch(scratch_t *w, int dim)
{
  if (w->big[dim]) return w->big[dim];
  batch_t *bt = calloc(1, sizeof(batch_t));
  if (!bt) return NULL;
  bt->map = malloc(sizeof(int) * w->maxraw * LB);
  bt->first = malloc(sizeof(int) * dim * LB);
  bt->x = malloc(sizeof(double) * dim * LB);
  if (!bt->map || !bt->first || !bt->x) {
    free(bt->map); free(bt->first); free(bt->x); free(bt);
    return NULL;
  }
  w->big[dim] = bt;
  return bt;
}

/* the patch in w (spokes() done) joins the batch of its size, which is solved when full */
static int solve_patch(const eq_ref *r, const eq_table *t, scratch_t *w, batch_t *batches,
                       double *defect)
{
  setup_patch(r, w, defect, 1);
  int dim = w->dim;
  if (dim == 0) {
    backsub(w, w->np, w->prow, w->ploc, w->map, w->rhs);
    return 0;
  }
  batch_t *bt = dim <= DENSE ? batches + dim : big_batch(w, dim);
  if (!bt) return 3;
  int b = bt->count++;
  if (dim <= DENSE)
    for (int i = 0; i < dim; ++i) {
      bt->x[i * LB + b] = w->rhs[i];
      for (int j = 0; j <= i; ++j) bt->A[(i * dim + j) * LB + b] = w->A[i * dim + j];
    }
  else
    memcpy(bt->first + b * dim, w->first, sizeof(int) * dim);
  if (dim > DENSE)   /* flush_big and backsub read the pairs' blocks: start the loads now */
    for (int p = 0; p < w->np; ++p) {
      const char *sb = (const char *)(CELL_WORK(w, w->prow[p]) + W_A(w->ploc[p]));
      for (int k = 0; k < (int)sizeof(double) * A_SIZE; k += 64) __builtin_prefetch(sb + k);
    }
  bt->np[b] = w->np;
  bt->prow[b] = w->prow;
  bt->ploc[b] = w->ploc;
  bt->pure[b] = w->pure;
  memcpy(bt->map + b * w->maxraw, w->map, sizeof(int) * w->np * DIM);
  if (bt->count < LB) return 0;
  return dim <= DENSE ? flush(r, t, w, bt, dim) : flush_big(r, t, w, bt, dim);
}

/* The patches of the vertices vlo <= g < vhi, in their order.  A cell's operators are
   computed (LB at a time, looking ahead) just before the first patch that needs them, into a
   work row, and mapped to alpha after its last pair is solved, when the row returns to a
   free list: the live rows are the front of cells between the patches solved and those to
   come, which stays in cache where the vertex order is local (DOLFINx orders vertices by
   Gibbs-Poole-Stockmeyer).  ``capacity``: the initial number of work rows (doubled when
   needed).  osc[c] = osc_T of each row evaluated.  stats[0] += the projected balance
   defect, stats[1] += the cell evaluations, stats[2] = the most work rows in use.  ``flow``:
   the dual-graph path (flow_block, solve_flow) instead of the hybridized patch systems. */
static int run_patches(const eq_ref *r, const eq_table *t, int64_t vlo, int64_t vhi,
                       int64_t capacity, double *alpha, double *osc, double *stats, int flow,
                       int sweeps)
{
  int64_t nv = vhi - vlo, total = 0;
  int64_t *start = calloc(nv + 1, sizeof(int64_t));
  if (!start) return 3;
  for (int64_t i = 0; i < t->n * NV; ++i) {
    int64_t g = t->gvert[i];
    if (g >= vlo && g < vhi) { ++start[g - vlo + 1]; ++total; }
  }
  int maxp = 0;
  for (int64_t v = 0; v < nv; ++v)
    { if (start[v + 1] > maxp) maxp = (int)start[v + 1]; start[v + 1] += start[v]; }
  int64_t cap = capacity > maxp + LB ? capacity : maxp + LB;
  int64_t *prow = malloc(sizeof(int64_t) * (total + 1));
  int *ploc = malloc(sizeof(int) * (total + 1));
  int64_t *cur = malloc(sizeof(int64_t) * (nv + 1));
  int64_t *slot = malloc(sizeof(int64_t) * (t->n + 1));
  int64_t *pend = malloc(sizeof(int64_t) * (maxp + LB));
  int nraw = maxp * DIM > 0 ? maxp * DIM : 1, maxdim = nraw * NF;
  scratch_t w;
  w.wsize = flow ? FW_SIZE : W_SIZE;
  w.sweeps = sweeps;
  w.kind = t->kind;
  w.fm = malloc(sizeof(double) * (maxp + 1) * DNF);
  w.fg = malloc(sizeof(double) * (maxp + 1) * DNF);
  w.ffa = malloc(sizeof(double) * (maxp + 1) * FA_SIZE);
  w.fs = malloc(sizeof(double) * nraw * 2 * NH * NH);
  w.fr1 = malloc(sizeof(int) * nraw);
  w.fmid = malloc(sizeof(double) * nraw * DIM);
  w.x = t->x;
  w.fr2 = malloc(sizeof(int) * nraw);
  w.fenv = malloc(sizeof(int) * nraw);
  w.work = malloc(sizeof(double) * w.wsize * cap);

  w.acc = malloc(sizeof(double) * ACC_SIZE * cap);
  w.left = malloc(sizeof(int) * cap);
  w.freel = malloc(sizeof(int64_t) * cap);
  w.nfree = 0;
  w.maxdeg = 2 * (DIM - 1) + 2;
  w.spoke = malloc(sizeof(int) * nraw);
  w.keys = malloc(sizeof(spoke_t) * nraw);
  w.raw = malloc(sizeof(spoke_t) * nraw);
  w.order = malloc(sizeof(int) * nraw);
  w.unknown = malloc(sizeof(int) * nraw);
  w.adj = malloc(sizeof(int) * nraw * w.maxdeg);
  w.deg = malloc(sizeof(int) * nraw);
  w.pos = malloc(sizeof(int) * nraw);
  w.queue = malloc(sizeof(int) * nraw);
  w.first = malloc(sizeof(int) * maxdim + nraw);
  w.A = malloc(sizeof(double) * (size_t)maxdim * maxdim);
  w.rhs = malloc(sizeof(double) * maxdim);
  w.slot = slot;
  w.alpha = alpha;
  w.maxraw = nraw;
  w.map = malloc(sizeof(int) * nraw);
  w.defect = stats;
  w.r = r;
  w.big = calloc(maxdim + 1, sizeof(batch_t *));
  w.P = NULL;
  w.Pcap = 0;
  w.off = malloc(sizeof(int64_t) * (maxdim + 1));
  w.fu = malloc(sizeof(int) * (maxdim + 1));
  w.dinvl = malloc(sizeof(double) * (maxdim + 1) * LB);
  w.mu = malloc(sizeof(double) * (maxdim + 1));
  batch_t batches[DENSE + 1];
  int ok = 1;
  for (int d = 0; d <= DENSE; ++d) {
    batches[d].count = 0;
    batches[d].map = malloc(sizeof(int) * nraw * LB);
    batches[d].A = malloc(sizeof(double) * (d * d + 1) * LB);
    batches[d].x = malloc(sizeof(double) * (d + 1) * LB);
    ok &= batches[d].map && batches[d].A && batches[d].x;
  }
  ok &= prow && ploc && cur && slot && pend && w.work && w.acc && w.left && w.freel && w.spoke;
  ok &= w.keys && w.raw && w.order && w.unknown && w.adj && w.deg && w.pos && w.queue && w.first;
  ok &= w.A && w.rhs && w.map && w.big && w.off && w.fu && w.dinvl && w.mu && w.fm && w.fg;
  ok &= w.ffa && w.fs && w.fmid && w.fr1 && w.fr2 && w.fenv;
  int err = ok ? 0 : 3;
  if (!err) {
    memcpy(cur, start, sizeof(int64_t) * nv);
    for (int64_t c = 0; c < t->n; ++c)
      for (int a = 0; a < NV; ++a) {
        int64_t g = t->gvert[c * NV + a];
        if (g >= vlo && g < vhi) { int64_t x = cur[g - vlo]++; prow[x] = c; ploc[x] = a; }
      }
    for (int64_t c = 0; c < t->n; ++c) slot[c] = -1;
  }
  int64_t used = 0, ahead = 0;     /* rows ever used; patches whose cells are computed */
  for (int64_t v = 0; v < nv && !err; ++v) {
    while (ahead <= v && !err) {   /* look ahead: the new cells of the next patches, >= LB */
      int npend = 0;
      for (; ahead < nv && npend < LB; ++ahead)
        for (int64_t x = start[ahead]; x < start[ahead + 1]; ++x) {
          int64_t c = prow[x];
          if (slot[c] >= 0) continue;
          if (w.nfree == 0 && used == cap) {          /* grow the work rows */
            cap *= 2;
            double *wk = realloc((void *)w.work, sizeof(double) * w.wsize * cap);
            double *ac = realloc(w.acc, sizeof(double) * ACC_SIZE * cap);
            int *lf = realloc(w.left, sizeof(int) * cap);
            int64_t *fr = realloc(w.freel, sizeof(int64_t) * cap);
            if (wk) w.work = wk;
            if (ac) w.acc = ac;
            if (lf) w.left = lf;
            if (fr) w.freel = fr;
            if (!wk || !ac || !lf || !fr) { err = 3; break; }
          }
          int64_t s = w.nfree ? w.freel[--w.nfree] : used++;
          slot[c] = s;
          int n = 0;
          for (int a = 0; a < NV; ++a)
            { int64_t g = t->gvert[c * NV + a]; n += g >= vlo && g < vhi; }
          w.left[s] = n;
          memset(w.acc + s * ACC_SIZE, 0, sizeof(double) * ACC_SIZE);
          pend[npend++] = c;
        }
      stats[1] += npend;
      for (int i = 0; i < npend && !err; i += LB) {
        int nb = npend - i < LB ? npend - i : LB;
        double *rows[LB], os[LB];
        LANES rows[b] = (double *)w.work + slot[pend[i + (b < nb ? b : 0)]] * w.wsize;
        if (flow ? flow_block(r, t, pend + i, nb, rows, os)
                 : cell_block(r, t, pend + i, nb, rows, vlo, vhi, os))
          err = 1;
        for (int b = 0; b < nb; ++b) osc[pend[i + b]] = os[b];
      }
      if (ahead == nv) break;
    }
    if (err || start[v + 1] == start[v]) continue;
    w.np = (int)(start[v + 1] - start[v]);
    w.prow = prow + start[v];
    w.ploc = ploc + start[v];
    spokes(t, &w);
    err = flow ? solve_flow(r, &w, stats) : solve_patch(r, t, &w, batches, stats);
  }
  for (int d = 1; d <= DENSE && !err; ++d) err = flush(r, t, &w, batches + d, d);
  for (int d = DENSE + 1; d <= maxdim && !err; ++d)
    if (w.big && w.big[d]) err = flush_big(r, t, &w, w.big[d], d);
  stats[2] = (double)used;
  for (int d = 0; d <= DENSE; ++d) { free(batches[d].map); free(batches[d].A); free(batches[d].x); }
  free(w.map);
  for (int d = 0; w.big && d <= maxdim; ++d)
    if (w.big[d]) { free(w.big[d]->map); free(w.big[d]->first); free(w.big[d]->x); free(w.big[d]); }
  free(w.fm); free(w.fg); free(w.ffa); free(w.fs); free(w.fmid);
  free(w.fr1); free(w.fr2); free(w.fenv);
  free(w.big); free(w.P); free(w.off); free(w.fu); free(w.dinvl); free(w.mu);
  free(w.spoke); free(w.keys); free(w.raw); free(w.order); free(w.unknown); free(w.adj);
  free(w.deg);
  free(w.pos); free(w.queue); free(w.first); free(w.A); free(w.rhs);
  free((void *)w.work); free(w.acc); free(w.left); free(w.freel);
  free(start); free(prow); free(ploc); free(cur); free(slot); free(pend);
  return err;
}

int eq_patches(const eq_ref *r, const eq_table *t, int64_t vlo, int64_t vhi, int64_t capacity,
               double *alpha, double *osc, double *stats)
{
  return run_patches(r, t, vlo, vhi, capacity, alpha, osc, stats, 0, 0);
}

int eq_flow(const eq_ref *r, const eq_table *t, int64_t vlo, int64_t vhi, int64_t capacity,
            double *alpha, double *osc, double *stats, int sweeps)
{
  return run_patches(r, t, vlo, vhi, capacity, alpha, osc, stats, 1, sweeps);
}
