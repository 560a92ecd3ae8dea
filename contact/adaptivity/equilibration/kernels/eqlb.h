/* The interface of the flux kernel (eqlb.c): the reference tables (eq_ref, the layouts of
   patches_c._tables) and the rows of a cell table (eq_table, those of cells.CellTable).
   compiled.py hands the declarations between the include guard to cffi (lines starting
   with '#' left out), so they are plain C declarations only. */
#ifndef CONTACT_EQUILIBRATION_EQLB_H
#define CONTACT_EQUILIBRATION_EQLB_H

#include <stdint.h>

typedef struct {
  const double *w, *ZZ, *ZR, *NZ, *NR, *P, *phiZ, *wlam, *DZG, *wlamQ, *wQ, *dphi, *dlam,
               *base, *R, *Z, *kappa, *Q, *q, *wS, *GL, *RL, *qint, *AR, *BR, *GT, *TB, *IZ, *EZ;
  const int64_t *lookup;
  double wsum;
} eq_ref;
typedef struct {
  int64_t n;
  const int64_t *gvert;
  const double *x, *U, *Ut, *f, *k;   /* Ut: the target's coefficients (τ = k∇(Σ Ut φ)), or NULL */
  int64_t fstride, kstride;       /* NQ, or 0 where f or k is one row for all cells */
  const int8_t *kind;
  const double *t, *tau, *src;
  const int64_t *cidx;
  const double *cmom;
} eq_table;
int64_t eq_work_size(void);
void eq_oscillation(const eq_ref *r, const eq_table *t, double *osc);
int eq_patches(const eq_ref *r, const eq_table *t, int64_t vlo, int64_t vhi, int64_t capacity,
               double *alpha, double *osc, double *stats);
int eq_flow(const eq_ref *r, const eq_table *t, int64_t vlo, int64_t vhi, int64_t capacity,
            double *alpha, double *osc, double *stats, int sweeps);

#endif
