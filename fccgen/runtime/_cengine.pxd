# Cython view of the C engine (fccgen/runtime/engine/*.h): the structs and functions
# the wrappers call. Only the fields the wrappers read are declared.
from ._model_table cimport fcc_element_class, fcc_model_table


cdef extern from "fcc_base.h":
    enum:
        FCC_ASM_M
        FCC_ASM_H
        FCC_ASM_F
        FCC_ASM_G
        FCC_ASM_B
        FCC_ASM_C
        FCC_ASM_E
        FCC_ASM_BODY
        FCC_ASM_KQ
        FCC_ASM_KV
        FCC_ASM_T
    enum:
        FCC_OK
        FCC_ERR_SINGULAR
        FCC_ERR_LAPACK
        FCC_ERR_NONFINITE_INPUT
        FCC_ERR_NONFINITE_RESULT
        FCC_ERR_DIVERGED
        FCC_ERR_PATTERN
        FCC_ERR_MEMORY
        FCC_ERR_NO_LAPACK
        FCC_ERR_ARGUMENT
    enum:
        FCC_AT_CALL
        FCC_AT_STAGE
        FCC_AT_POSITIONS
        FCC_AT_VELOCITIES
        FCC_AT_STEP
    enum:
        FCC_RUN_DONE
        FCC_RUN_PAUSE
        FCC_RUN_ERROR
        FCC_RUN_UNDERFLOW

    int fcc_finite(const double *x, long n) noexcept nogil


cdef extern from "fcc_assemble.h":
    ctypedef struct fcc_model:
        const fcc_model_table *table
        int n_q, n_g, n_el, n_bodies, n_p, n_time
        const fcc_element_class **cls
        int *qptr
        int *qidx
        int *pptr
        int *gptr
        int *body_of
        int *row_group
        int *time_slot

    ctypedef struct fcc_assembly:
        const fcc_model *model
        double *params
        double t
        double *lq
        double *lv
        double *out
        double *zeros
        double *M
        double *h
        double *f
        double *g
        double *B
        double *c
        double energy[2]
        double *body
        double *fq
        double *fv
        double *gt

    int fcc_model_init(fcc_model *m, const fcc_model_table *table, int n_q, int n_el,
                       const int *class_of, const int *qptr, const int *qidx,
                       const int *pptr, int n_bodies, const int *body_elements,
                       int n_time, const int *time_slots) nogil
    void fcc_model_free(fcc_model *m) nogil
    int fcc_model_set_time_slots(fcc_model *m, int n_time, const int *time_slots) nogil
    int fcc_assembly_init(fcc_assembly *a, const fcc_model *m,
                          const double *params) nogil
    void fcc_assembly_free(fcc_assembly *a) nogil
    void fcc_put_time(fcc_assembly *a, double t) noexcept nogil
    void fcc_assemble(fcc_assembly *a, const double *q, const double *v,
                      int flags) noexcept nogil
    double fcc_scaled_residual(const fcc_assembly *a) noexcept nogil
    double fcc_max_abs_g(const fcc_assembly *a) noexcept nogil
    int fcc_kernel_flags(const fcc_model *m) noexcept nogil
    long fcc_jacobian_size(const fcc_model *m) noexcept nogil
    void fcc_jacobian_triplets(fcc_assembly *a, const double *q, int *rows, int *cols,
                               double *vals) noexcept nogil
    void fcc_element_vectors(const fcc_element_class *k, const double *lq,
                             const double *lv, const double *p, const int *idx, int row,
                             int flags, double *o, double *h, double *f,
                             double *c) noexcept nogil
