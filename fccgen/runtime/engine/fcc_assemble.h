/* Assembly of the global quantities from a generated module's element kernels.
 *
 * fcc_model holds the constants: the kernel table and which class, coordinates,
 * parameters and constraint rows each element has. fcc_assembly holds one instance's
 * numbers: its parameters (with the time written into the slots named "t"), and the
 * assembled M, h, f, g, B, c, energy, body outputs, df/dq, df/dq', dg/dt. One model
 * serves any number of assemblies.
 */
#ifndef FCC_ASSEMBLE_H
#define FCC_ASSEMBLE_H

#include "fcc_base.h"

typedef struct fcc_model {
    const fcc_model_table *table;
    int n_q;                       /* global coordinates */
    int n_g;                       /* constraint rows */
    int n_el;                      /* elements */
    int n_bodies;                  /* bodies (rows of the body outputs) */
    int n_p;                       /* parameters of all elements */
    int n_time;                    /* parameter slots named "t" */
    int out_size;                  /* the largest kernel output */
    int local_size;                /* the largest element's coordinates */
    int g_max;                     /* the largest element's constraint rows */
    const fcc_element_class **cls; /* per element: its class */
    int *qptr;                     /* per element: start in qidx (n_el + 1) */
    int *qidx;                     /* global coordinate index of each local one */
    int *pptr;                     /* per element: start in the parameters (n_el + 1) */
    int *gptr;                     /* per element: first constraint row (n_el + 1) */
    int *body_of;                  /* per element: body index or -1 */
    int *row_group;                /* per row: its element's first row */
    int *time_slot;                /* the parameter slots named "t" */
} fcc_model;

typedef struct fcc_assembly {
    const fcc_model *model;
    double *params;                /* n_p: the elements' parameters, concatenated */
    double t;                      /* the time written into the time slots */
    double *lq, *lv, *out;         /* an element's gathered q, v; a kernel's output */
    double *zeros;                 /* n_q zeros: v for kernels of q alone */
    double *M, *h, *f, *g, *B, *c; /* assembled quantities (M, B dense, row-major) */
    double energy[2];              /* kinetic, potential */
    double *body;                  /* 6 per body: mass centre, angular velocity */
    double *fq, *fv;               /* df/dq, df/dq' */
    double *gt;                    /* partial dg/dt */
} fcc_assembly;

/* The model of n_el elements: class_of[e] indexes table->classes; qptr/qidx,
 * pptr: each element's global coordinates and the start of its parameters (CSR
 * style); body_elements[j]: the element of body j; time_slots: the parameter slots
 * named "t". Indices are the caller's to check. Returns FCC_OK or FCC_ERR_MEMORY. */
int fcc_model_init(fcc_model *m, const fcc_model_table *table, int n_q, int n_el,
                   const int *class_of, const int *qptr, const int *qidx,
                   const int *pptr, int n_bodies, const int *body_elements,
                   int n_time, const int *time_slots);
void fcc_model_free(fcc_model *m);
/* Replace the time slots (set-up). */
int fcc_model_set_time_slots(fcc_model *m, int n_time, const int *time_slots);

/* An assembly of the model with the given parameters (n_p numbers, copied). */
int fcc_assembly_init(fcc_assembly *a, const fcc_model *m, const double *params);
void fcc_assembly_free(fcc_assembly *a);

/* Write t into every time slot: later assemblies evaluate at t. */
void fcc_put_time(fcc_assembly *a, double t);
/* Assemble the quantities named by flags (FCC_ASM_*) at (q, v); v may be NULL when
 * only kernels of q are asked for. */
void fcc_assemble(fcc_assembly *a, const double *q, const double *v, int flags);
/* max_k |g_k| / ||B_k|| of the assembled g and B (|g_k| for a zero row); NaN if a
 * g_k is not finite. */
double fcc_scaled_residual(const fcc_assembly *a);
/* max_k |g_k| (NaN if one is NaN). */
double fcc_max_abs_g(const fcc_assembly *a);
/* FCC_ASM_* bits of the kernels at least one element's class has. */
int fcc_kernel_flags(const fcc_model *m);
/* Entries of the element blocks of B (fcc_jacobian_triplets writes that many). */
long fcc_jacobian_size(const fcc_model *m);
/* B at q as (row, column, value) triplets, one per entry of each element's block
 * (a coordinate shared by elements repeats). */
void fcc_jacobian_triplets(fcc_assembly *a, const double *q, int *rows, int *cols,
                           double *vals);

/* One element's h (FCC_ASM_H), f (FCC_ASM_F) and c (FCC_ASM_C) at its gathered
 * (lq, lv), added into h and f at its coordinates idx and written into c from its
 * first row; o: room for the kernel's output. */
static inline void fcc_element_vectors(const fcc_element_class *k, const double *lq,
                                       const double *lv, const double *p,
                                       const int *idx, int row, int flags, double *o,
                                       double *h, double *f, double *c)
{
    int i;
    if (flags & FCC_ASM_H && k->h_vector != NULL) {
        k->h_vector(lq, lv, p, o);
        for (i = 0; i < k->n_q; i++)
            h[idx[i]] += o[i];
    }
    if (flags & FCC_ASM_F && k->applied_forces != NULL) {
        k->applied_forces(lq, lv, p, o);
        for (i = 0; i < k->n_q; i++)
            f[idx[i]] += o[i];
    }
    if (flags & FCC_ASM_C && k->constraint_bias != NULL) {
        k->constraint_bias(lq, lv, p, o);
        for (i = 0; i < k->n_g; i++)
            c[row + i] = o[i];
    }
}

#endif
