/* The dense LU solve shared by the kernels of eqlb.c and stress.c. */
#ifndef CONTACT_EQUILIBRATION_LU_H
#define CONTACT_EQUILIBRATION_LU_H

#include <math.h>

/* Solve A X = B (n x n, row-major, nrhs columns) by LU with partial pivoting, in place;
   returns 1 if a pivot is exactly zero. */
static int lu_solve(int n, double *A, double *B, int nrhs)
{
  for (int k = 0; k < n; ++k) {
    int piv = k;
    double best = fabs(A[k * n + k]);
    for (int i = k + 1; i < n; ++i)
      if (fabs(A[i * n + k]) > best) { best = fabs(A[i * n + k]); piv = i; }
    if (best == 0.0) return 1;
    if (piv != k) {
      for (int j = 0; j < n; ++j)
        { double s = A[k * n + j]; A[k * n + j] = A[piv * n + j]; A[piv * n + j] = s; }
      for (int j = 0; j < nrhs; ++j)
        { double s = B[k * nrhs + j]; B[k * nrhs + j] = B[piv * nrhs + j]; B[piv * nrhs + j] = s; }
    }
    double inv = 1.0 / A[k * n + k];
    for (int i = k + 1; i < n; ++i) {
      double l = A[i * n + k] * inv;
      if (l == 0.0) continue;
      for (int j = k + 1; j < n; ++j) A[i * n + j] -= l * A[k * n + j];
      for (int j = 0; j < nrhs; ++j) B[i * nrhs + j] -= l * B[k * nrhs + j];
    }
  }
  for (int k = n - 1; k >= 0; --k)
    for (int j = 0; j < nrhs; ++j) {
      double s = B[k * nrhs + j];
      for (int i = k + 1; i < n; ++i) s -= A[k * n + i] * B[i * nrhs + j];
      B[k * nrhs + j] = s / A[k * n + k];
    }
  return 0;
}

#endif
