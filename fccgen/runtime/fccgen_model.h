/* The interface between a generated kernel module and the fccgen runtime.
 *
 * A generated module holds one fcc_element_class per element class of its model
 * (see fccgen/plan/classes.py for the layouts) and hands a pointer to its
 * fcc_model_table to the runtime in a PyCapsule named FCC_CAPSULE_NAME.
 *
 * Kernel arguments: q and v are the element's local coordinates and speeds (its
 * moving triples, 3 numbers each), p its parameters; out is written, never read.
 * Matrices are row-major. A kernel pointer is NULL when the quantity is identically
 * zero for the class (no gravity, no constraint rows, ...).
 *
 * Time: a class whose equations depend on the time t has a parameter named "t"
 * (its slot in p); the runtime writes the current t there before evaluating. Its
 * constraint_rate is dg/dt (NULL for a class whose constraints do not depend on t),
 * and its constraint_bias keeps the meaning g'' - B q'': (dB/dt) v + 2 (d/dt)(B) v
 * + d2g/dt2, the partial time derivatives included.
 */
#ifndef FCCGEN_MODEL_H
#define FCCGEN_MODEL_H

#define FCC_ABI_VERSION 3
#define FCC_CAPSULE_NAME "fccgen.model_table"

typedef void (*fcc_kernel_q)(const double *q, const double *p, double *out);
typedef void (*fcc_kernel_qv)(const double *q, const double *v, const double *p, double *out);

typedef struct {
    const char *name;                     /* class name, e.g. "body_1a2b3c4d" */
    int n_q;                              /* local coordinates */
    int n_p;                              /* parameters */
    int n_g;                              /* constraint rows */
    fcc_kernel_q  mass_matrix;            /* out[n_q*n_q]: M */
    fcc_kernel_qv h_vector;               /* out[n_q]: inertia terms h */
    fcc_kernel_qv applied_forces;         /* out[n_q]: generalized applied forces f */
    fcc_kernel_q  constraints;            /* out[n_g]: g */
    fcc_kernel_q  constraint_jacobian;    /* out[n_g*n_q]: B = dg/dq */
    fcc_kernel_qv constraint_bias;        /* out[n_g]: g'' - B q'' (with the time terms) */
    fcc_kernel_qv energy;                 /* out[2]: kinetic, potential */
    fcc_kernel_qv body_outputs;           /* out[6]: mass centre, angular velocity */
    fcc_kernel_qv force_jacobian_q;       /* out[n_q*n_q]: df/dq (K = -df/dq) */
    fcc_kernel_q  force_jacobian_v;       /* out[n_q*n_q]: df/dq' (C = -df/dq') */
    fcc_kernel_q  constraint_rate;        /* out[n_g]: partial dg/dt (rheonomic rows) */
} fcc_element_class;

typedef struct {
    int abi_version;                      /* FCC_ABI_VERSION */
    const char *structure_hash;           /* hash of the class keys it was built for */
    int n_classes;
    const fcc_element_class *classes;
} fcc_model_table;

#endif
