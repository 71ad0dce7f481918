/* The interface between a generated parameter-derivative module and the fccgen
 * runtime (fccgen/sensitivity/build.py).
 *
 * One fcc_dp_class per element class of the model, in the order of the model's kernel
 * table. Its kernels are d/dp_j of the element kernels of fccgen_model.h that depend
 * on the parameters, all with the signature (q, v, p, out):
 *   out[j * size + k] = d K_k / d p_j   (parameter-major; K row-major, size numbers)
 * with K = M (n_q*n_q), h (n_q), f (n_q), g (n_g), B (n_g*n_q), the constraint bias
 * (n_g). A pointer is NULL when that derivative is identically zero for the class.
 */
#ifndef FCC_DP_TABLE_H
#define FCC_DP_TABLE_H

#define FCC_DP_ABI_VERSION 4
#define FCC_DP_CAPSULE_NAME "fccgen.dp_table"

enum { FCC_DP_MASS, FCC_DP_H, FCC_DP_F, FCC_DP_G, FCC_DP_B, FCC_DP_BIAS, FCC_DP_N };

typedef void (*fcc_dp_kernel)(const double *q, const double *v, const double *p,
                              double *out);

/* The tangent kernel: with R1 = f - h - M a - B^T lam (n_q), R2 = -bias - B a (n_g)
 * and Phi = B v + dg/dt (n_g), the directional derivatives along (dq, dv, dp):
 *   out = [dR1[dq, dv, dp] (n_q); dR2[dq, dv, dp] (n_g); (dg/dp) dp (n_g);
 *          dPhi[dq, dp] (n_g)]
 * a: the element's accelerations (n_q), lam its multipliers (n_g). */
typedef void (*fcc_dp_tangent)(const double *q, const double *v, const double *p,
                               const double *a, const double *lam, const double *dq,
                               const double *dv, const double *dp, double *out);

/* The tangent in parts. Its outputs are linear in the direction: out = J [dq; dv; dp]
 * with J depending on (q, v, p, a, lam) only. prepare evaluates the entries of J's
 * state columns (those of dq and dv: n_w numbers) into w once per state; apply forms
 * J_state [dq; dv] from w along one direction, as often as there are directions at
 * that state; column writes parameter c's column J[:, 2 n_q + c] (n_q + 3 n_g numbers),
 * needed only where some direction's dp_c is not zero (a design parameter moves few
 * of an element's numbers). tangent is prepare, apply, and dp_c times each column. */
typedef void (*fcc_dp_prepare)(const double *q, const double *v, const double *p,
                               const double *a, const double *lam, double *w);
typedef void (*fcc_dp_apply)(const double *w, const double *dq, const double *dv,
                             double *out);
typedef void (*fcc_dp_column)(const double *q, const double *v, const double *p,
                              const double *a, const double *lam, int c, double *out);

typedef struct {
    const char *name;                     /* the element class's name */
    int n_q, n_p, n_g;
    fcc_dp_kernel k[FCC_DP_N];            /* indexed by FCC_DP_MASS ... FCC_DP_BIAS */
    fcc_dp_tangent tangent;               /* never NULL */
    int n_w;                              /* numbers prepare writes */
    fcc_dp_prepare prepare;               /* never NULL */
    fcc_dp_apply apply;                   /* never NULL */
    fcc_dp_column column;                 /* never NULL */
} fcc_dp_class;

typedef struct {
    int abi_version;                      /* FCC_DP_ABI_VERSION */
    const char *structure_hash;           /* hash of the class keys it was built for */
    int n_classes;
    const fcc_dp_class *classes;
} fcc_dp_table;

#endif
