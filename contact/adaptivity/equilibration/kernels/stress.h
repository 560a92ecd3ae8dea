/* The interface of the stress kernel (stress.c): the cell operators and the vertex-patch
   μ-systems of the equilibrated stress (stress_c.py).  compiled.py hands the declarations
   between the include guard to cffi (lines starting with '#' left out). */
#ifndef CONTACT_EQUILIBRATION_STRESS_H
#define CONTACT_EQUILIBRATION_STRESS_H

#include <stdint.h>

int st_cells(int64_t n, const double *J, const double *s, const double *absdet, const double *ZZ,
             const double *ZR, const double *W, const double *M1Z, const double *M1R,
             const double *OZ, const double *OR, const double *q0, const double *beta,
             const double *mas, double *S, double *gamma0, double *h, double *POt);
int st_patches(int64_t npatch, const int64_t *pstart, const int64_t *prow, const int32_t *ploc,
               const int64_t *idx, const int64_t *pdim, const double *S, const double *hp,
               const double *dp, double *mu, double *defect);

#endif
