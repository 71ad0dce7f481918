/* Forward sensitivities carried by DOPRI5 (fcc_sens_dopri5.h): the stages of s by
 * the method's tableau, their error estimate and continuous extension. */
#include <math.h>
#include <string.h>

#include "fcc_sens_dopri5.h"

enum { Y1, YT, KEEP, K1, RC0 = K1 + 7, N_BLOCKS = RC0 + 5 };
typedef char blocks_match_the_header[N_BLOCKS == FCC_SENS_DOPRI5_WORK ? 1 : -1];

/* Parameter j's 2 n numbers of block b. */
static double *block(const fcc_sens_dp5 *d, double *b, int j)
{
    return b + (size_t)j * 2 * (size_t)d->s->n;
}

void fcc_sens_dp5_start(fcc_sens_dp5 *d)
{
    size_t size = (size_t)d->s->np * 2 * (size_t)d->s->n;
    int i;
    d->y1 = d->work + Y1 * size;
    d->yt = d->work + YT * size;
    d->keep = d->work + KEEP * size;
    for (i = 0; i < 7; i++)
        d->k[i] = d->work + (K1 + i) * size;
    for (i = 0; i < 5; i++)
        d->rc[i] = d->work + (RC0 + i) * size;
}

/* The state's s of parameter j into y (2 n), or y into it (put). */
static void state(fcc_sens_dp5 *d, int j, double *y, int put)
{
    int n = d->s->n;
    double *sq = fcc_sens_sq(d->s, j), *sv = fcc_sens_sv(d->s, j);
    if (put) {
        memcpy(sq, y, (size_t)n * sizeof(double));
        memcpy(sv, y + n, (size_t)n * sizeof(double));
    } else {
        memcpy(y, sq, (size_t)n * sizeof(double));
        memcpy(y + n, sv, (size_t)n * sizeof(double));
    }
}

int fcc_sens_dp5_stage(fcc_engine *e, fcc_sens_dp5 *d, int k, double h,
                       const double *w, const double *q, const double *v,
                       const double *a)
{
    fcc_sens *s = d->s;
    int i, j, l, n = s->n;
    double *arg, *kk, acc;
    fcc_sens_stage_begin(e, s, q, v, a);
    for (j = 0; j < s->np; j++) {
        arg = block(d, k == 7 ? d->y1 : d->yt, j);
        state(d, j, arg, 0);
        if (k > 1)
            for (i = 0; i < 2 * n; i++) {
                acc = 0.0;
                for (l = 0; l < k - 1; l++)
                    if (w[l] != 0.0)
                        acc += w[l] * block(d, d->k[l], j)[i];
                arg[i] += h * acc;
            }
        kk = block(d, d->k[k - 1], j);
        memcpy(kk, arg + n, (size_t)n * sizeof(double));
        if (fcc_sens_stage_acc(e, s, j, q, v, a, arg, arg + n, kk + n) < 0)
            return -1;
    }
    return 0;
}

double fcc_sens_dp5_error(const fcc_sens_dp5 *d, double h, const double *ew,
                          double atol, double rtol)
{
    const fcc_sens *s = d->s;
    int i, j, l, n2 = 2 * s->n;
    double worst = 0.0, acc, dd, sk, at;
    const double *y1, *yk;
    if (!d->control)
        return 0.0;
    for (j = 0; j < s->np; j++) {
        at = atol / d->scale[j];
        y1 = block(d, d->y1, j);
        acc = 0.0;
        for (i = 0; i < n2; i++) {
            dd = 0.0;
            for (l = 0; l < 7; l++)
                if (ew[l] != 0.0)
                    dd += ew[l] * block(d, d->k[l], j)[i];
            dd *= h;
            yk = i < s->n ? fcc_sens_sq(s, j) + i : fcc_sens_sv(s, j) + (i - s->n);
            sk = at + rtol * fmax(fabs(*yk), fabs(y1[i]));
            acc += (dd / sk) * (dd / sk);
        }
        acc = sqrt(acc / n2);
        if (!(acc <= worst))                   /* NaN stays NaN: a rejection */
            worst = acc;
    }
    return worst;
}

void fcc_sens_dp5_dense(fcc_sens_dp5 *d, double h, const double *dw)
{
    const fcc_sens *s = d->s;
    int i, j, l, n2 = 2 * s->n;
    double dy, bspl, y0, acc;
    for (j = 0; j < s->np; j++)
        for (i = 0; i < n2; i++) {
            y0 = i < s->n ? fcc_sens_sq(s, j)[i] : fcc_sens_sv(s, j)[i - s->n];
            dy = block(d, d->y1, j)[i] - y0;
            bspl = h * block(d, d->k[0], j)[i] - dy;
            acc = 0.0;
            for (l = 0; l < 7; l++)
                if (dw[l] != 0.0)
                    acc += dw[l] * block(d, d->k[l], j)[i];
            block(d, d->rc[0], j)[i] = y0;
            block(d, d->rc[1], j)[i] = dy;
            block(d, d->rc[2], j)[i] = bspl;
            block(d, d->rc[3], j)[i] = dy - h * block(d, d->k[6], j)[i] - bspl;
            block(d, d->rc[4], j)[i] = h * acc;
        }
}

/* The continuous extension at th into yt (th = 1: y1 itself). */
static void dense_at(fcc_sens_dp5 *d, double th)
{
    size_t i, size = (size_t)d->s->np * 2 * (size_t)d->s->n;
    double th1 = 1.0 - th;
    if (th == 1.0) {
        memcpy(d->yt, d->y1, size * sizeof(double));
        return;
    }
    for (i = 0; i < size; i++)
        d->yt[i] = d->rc[0][i] + th * (d->rc[1][i] + th1 * (
            d->rc[2][i] + th * (d->rc[3][i] + th1 * d->rc[4][i])));
}

void fcc_sens_dp5_take(fcc_sens_dp5 *d, double th)
{
    int j;
    dense_at(d, th);
    for (j = 0; j < d->s->np; j++)
        state(d, j, block(d, d->yt, j), 1);
}

void fcc_sens_dp5_output(fcc_sens_dp5 *d, double th)
{
    int j;
    for (j = 0; j < d->s->np; j++)
        state(d, j, block(d, d->keep, j), 0);
    fcc_sens_dp5_take(d, th);
}

void fcc_sens_dp5_restore(fcc_sens_dp5 *d)
{
    int j;
    for (j = 0; j < d->s->np; j++)
        state(d, j, block(d, d->keep, j), 1);
}
