/* The interface between a generated event module and the fccgen runtime
 * (fccgen/runtime/_events.pyx).
 *
 * A generated event module hands a pointer to its fcc_event_table to the runtime in a
 * PyCapsule named FCC_EVENT_CAPSULE_NAME. Kernel arguments: q and v the model's global
 * coordinates and speeds (n_q each), t the time, p the runtime parameters (n_p: per
 * joint angle its reference theta_r, cos theta_r, sin theta_r); out is written, never
 * read. Matrices are row-major, n_q columns.
 */
#ifndef FCCGEN_EVENTS_H
#define FCCGEN_EVENTS_H

#define FCC_EVENT_ABI_VERSION 2
#define FCC_EVENT_CAPSULE_NAME "fccgen.event_table"

typedef void (*fcc_event_kernel)(const double *q, const double *v, double t,
                                 const double *p, double *out);

typedef struct {
    int abi_version;                      /* FCC_EVENT_ABI_VERSION */
    int n_q;
    int n_p;
    int n_events;
    int n_quantities;
    fcc_event_kernel event_values;        /* out[n_events]: s_k(q, v, t) */
    fcc_event_kernel event_gradients;     /* out[n_events*n_q]: ds_k/dq */
    fcc_event_kernel quantity_values;     /* out[n_quantities]: joint angles, slides */
    fcc_event_kernel quantity_gradients;  /* out[n_quantities*n_q]: their Jacobian */
    fcc_event_kernel quantity_bias;       /* out[n_quantities]: (d/dt Jacobian) v */
    /* The Jacobian's structural nonzeros (the entries quantity_gradients may write
     * other than 0), row by row: row j's are gradient_ptr[j] .. gradient_ptr[j+1] - 1,
     * in the columns gradient_idx (increasing in a row); quantity_gradient_values
     * writes them, out[n_gradient_nz], the same numbers as quantity_gradients. */
    int n_gradient_nz;
    const int *gradient_ptr;              /* [n_quantities + 1] */
    const int *gradient_idx;              /* [n_gradient_nz] */
    fcc_event_kernel quantity_gradient_values;
} fcc_event_table;

#endif
