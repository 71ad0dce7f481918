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

    ctypedef struct fcc_lapack:
        void (*dgeqp3)(int *m, int *n, double *a, int *lda, int *jpvt, double *tau,
                       double *work, int *lwork, int *info) noexcept nogil
        void (*dormqr)(char *side, char *trans, int *m, int *n, int *k, double *a,
                       int *lda, double *tau, double *c, int *ldc, double *work,
                       int *lwork, int *info) noexcept nogil
        void (*dgesvd)(char *jobu, char *jobvt, int *m, int *n, double *a, int *lda,
                       double *s, double *u, int *ldu, double *vt, int *ldvt,
                       double *work, int *lwork, int *info) noexcept nogil
        void (*dpotrf)(char *uplo, int *n, double *a, int *lda, int *info) noexcept nogil
        void (*dpotrs)(char *uplo, int *n, int *nrhs, double *a, int *lda, double *b,
                       int *ldb, int *info) noexcept nogil
        void (*dgetrf)(int *m, int *n, double *a, int *lda, int *ipiv,
                       int *info) noexcept nogil
        void (*dgetrs)(char *trans, int *n, int *nrhs, double *a, int *lda, int *ipiv,
                       double *b, int *ldb, int *info) noexcept nogil
        void (*dgemm)(char *transa, char *transb, int *m, int *n, int *k, double *alpha,
                      double *a, int *lda, double *b, int *ldb, double *beta, double *c,
                      int *ldc) noexcept nogil

    ctypedef struct fcc_settings:
        double rank_tol
        double position_tol
        int max_newton
        double grow_tol
        double decide_tol
        double ambiguous_low
        double row_floor

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


cdef extern from "fcc_dense.h":
    int FCC_DENSE_NO_LAPACK
    ctypedef struct fcc_dense:
        const fcc_lapack *lapack
        int n, m, r, nr
        double rank_tol
        int rank_fixed
        double grow_trigger
        int check_growth
        int grew
        long n_factor, n_drop, n_svd
        double kept_min, dropped_max
        double *sigma
        const int *group
        double *A

    int fcc_dense_init(fcc_dense *s, int n, int m, double rank_tol, double grow_tol,
                       double row_floor, const fcc_lapack *lapack) nogil
    void fcc_dense_free(fcc_dense *s) nogil
    void fcc_dense_reset_stats(fcc_dense *s) noexcept nogil
    int fcc_dense_svd_rank(fcc_dense *s, const double *B, double tol) noexcept nogil
    int fcc_dense_factor(fcc_dense *s, const double *M, const double *B) noexcept nogil
    void fcc_dense_apply(fcc_dense *s, const double *Q, const double *w, const double *b,
                         double *x) noexcept nogil


cdef extern from "fcc_ldl.h":
    void fcc_ldl_symbolic(int n, const int *Ap, const int *Ai, int *Lp, int *parent,
                          int *Lnz, int *flag) noexcept nogil
    void fcc_ldl_rows(int n, const int *Ap, const int *Ai, const int *Lp,
                      const int *parent, int *Lnz, int *Li, int *Rp, int *Rj, int *Rpos,
                      int *pattern, int *flag) noexcept nogil
    int fcc_ldl_numeric(int n, const int *Ap, const int *Ai, const double *Ax,
                        const int *Lp, const int *Li, const int *Rp, const int *Rj,
                        const int *Rpos, double *Lx, double *Dinv, double *Y,
                        double pivot_tol) noexcept nogil
    void fcc_ldl_solve(int n, const int *Lp, const int *Li, const double *Lx,
                       const double *Dinv, double *x) noexcept nogil

