/* Dense Cholesky factors of small symmetric positive definite matrices
 * (the discriminants' covariances: lda.c at build, shape.c per frame with
 * landmarks missing). Written here rather than called from LAPACK: at
 * 48 x 48 a call of OpenBLAS's dpotrf costs more in its threading and
 * layout handling than the factor does. */
#include "internal.h"

#include <math.h>

int mim__cholesky(double *a, uint32_t n)
{
    for (uint32_t j = 0; j < n; j++) {
        double *aj = a + (size_t)j * n;
        double s = aj[j];
        for (uint32_t k = 0; k < j; k++) s -= aj[k] * aj[k];
        if (!(s > 0)) return -1;
        aj[j] = sqrt(s);
        for (uint32_t i = j + 1; i < n; i++) {
            double *ai = a + (size_t)i * n, t = ai[j];
            for (uint32_t k = 0; k < j; k++) t -= ai[k] * aj[k];
            ai[j] = t / aj[j];
        }
    }
    return 0;
}

double mim__chol_forward(const double *l, uint32_t n, double *x)
{
    double q = 0;
    for (uint32_t i = 0; i < n; i++) {
        const double *li = l + (size_t)i * n;
        double s = x[i];
        for (uint32_t k = 0; k < i; k++) s -= li[k] * x[k];
        x[i] = s / li[i];
        q += x[i] * x[i];
    }
    return q;
}

void mim__chol_solve(const double *l, uint32_t n, double *x)
{
    mim__chol_forward(l, n, x);
    for (uint32_t i = n; i-- > 0;) {
        double s = x[i];
        for (uint32_t k = i + 1; k < n; k++) s -= l[(size_t)k * n + i] * x[k];
        x[i] = s / l[(size_t)i * n + i];
    }
}
