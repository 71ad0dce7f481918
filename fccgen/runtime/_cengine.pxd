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


cdef extern from "fcc_engine.h":
    enum:
        FCC_RANK_LOG_SIZE
        FCC_TRACK_MAX
        FCC_DENSE_FALLBACK_MAX
        FCC_REFINE_MAX
        FCC_CG_MAX
        FCC_AL_MAX

    ctypedef struct fcc_pattern:
        const fcc_model *model
        int n, m
        int *mptr
        int *bptr
        int compact
        int *snq
        int *sptr
        int *sidx
        int *sloc
        int *sng
        int *sgptr
        int *srow
        int *srloc
        int *mcptr
        int *bcptr
        double *efix
        int n_pinned
        int *pinned
        int n_fixed
        int *fixed_off
        double *fixed_val
        double *fixed_tol
        int n_fixed_rows
        int *fixed_rows
        double *fixed_norm
        double *fixed_g_tol
        int n_zero_m, n_zero_b
        int *zero_m
        int *zero_b
        double *zero_m_tol
        double *zero_b_tol
        int ready, n_lead, nnz_a, nnz_l
        int *perm
        int *Ap
        int *Ai
        int *ent_ptr
        int *ent_a
        int *ent_b
        int *ent_pos
        int n_sw
        int *sw_ptr
        int *sw_idx
        int *sw_ent_ptr
        int *sw_ent_a
        int *sw_ent_b
        int *sw_ent_pos

    ctypedef struct fcc_sparse:
        const fcc_pattern *pat
        double *Mblk
        double *Bblk
        double *alpha
        int held, tripped
        long n_factor
        long n_boosted
        double *track
        int warm_valid
        long n_solves, n_iterations, n_unconverged, n_beyond_rank
        double beyond_quotient
        int ms
        int sw_live
        int most_iterations
        int cg_max, refine_max, al_max
        int n_track
        double grow_trigger, bound_max
        long n_svd, n_fallback, n_chord, n_chord_undone
        int dense_fallback_max
        void (*restart_watch)(void *ctx, fcc_engine *e) noexcept nogil
        void *restart_ctx

    ctypedef struct fcc_engine:
        fcc_assembly *asmb
        const fcc_model *model
        const fcc_lapack *lapack
        fcc_settings set
        int n, m
        fcc_dense sol
        double diverge_residual
        double *rhs
        double *nb
        double *dq
        double *vtmp
        double *stages
        int factor_valid, b_fresh, running
        double ke_peak, ke_cut_max, ke_cut_t
        int n_rank_log
        double rank_log[64][3]
        int err, err_info, err_where, err_stage, err_detail
        double err_t, err_h, err_value, err_bound
        int sparse
        fcc_sparse sp

    int fcc_engine_init(fcc_engine *e, fcc_assembly *a, const fcc_lapack *lapack,
                        const fcc_settings *settings) nogil
    void fcc_engine_free(fcc_engine *e) nogil
    void fcc_engine_decide_rank(fcc_engine *e, int rank) noexcept nogil
    const char *fcc_engine_message(fcc_engine *e) noexcept nogil
    int fcc_fail(fcc_engine *e, int code, int info, int detail) noexcept nogil
    int fcc_nonfinite_input(fcc_engine *e, const double *q, const double *v,
                            int flags) noexcept nogil
    int fcc_check_result(fcc_engine *e, const double *q, const double *v,
                         const double *a, int flags) noexcept nogil
    int fcc_factor(fcc_engine *e, const double *q) noexcept nogil
    int fcc_accelerations(fcc_engine *e, const double *q, const double *v, double *a,
                          int reuse) noexcept nogil
    int fcc_baumgarte(fcc_engine *e, const double *q, const double *v, double *a,
                      double alpha, double beta) noexcept nogil
    int fcc_project_positions(fcc_engine *e, double *q, int *iterations,
                              int reuse) noexcept nogil
    int fcc_project_velocities(fcc_engine *e, const double *q, double *v,
                               int have_B) noexcept nogil
    double fcc_constraint_residual(fcc_engine *e) noexcept nogil
    void fcc_solve_constrained(fcc_engine *e, const double *Q, const double *w,
                               const double *b, double *x) noexcept nogil

    int fcc_pattern_init(fcc_pattern *P, const fcc_model *m) nogil
    void fcc_pattern_free(fcc_pattern *P) nogil
    int fcc_pattern_set_view(fcc_pattern *P, const int *snq, const int *sloc,
                             const int *sng, const int *srloc, const double *efix,
                             int n_pinned, const int *pinned, int n_fixed_rows,
                             const int *fixed_rows, const double *fixed_norm,
                             const double *fixed_g_tol, int n_fixed,
                             const int *fixed_off, const double *fixed_val,
                             const double *fixed_tol) nogil
    int fcc_pattern_set_guards(fcc_pattern *P, int n_zero_m, const int *zero_m,
                               const double *zero_m_tol, int n_zero_b,
                               const int *zero_b, const double *zero_b_tol) nogil
    int fcc_pattern_set_structure(fcc_pattern *P, const int *perm, const int *Ap,
                                  const int *Ai, const int *ent_ptr, const int *ent_a,
                                  const int *ent_b, const int *ent_pos) nogil
    int fcc_pattern_set_switchable(fcc_pattern *P, int n_sw, const int *sw_ptr,
                                   const int *sw_idx, const int *sw_ent_ptr,
                                   const int *sw_ent_a, const int *sw_ent_b,
                                   const int *sw_ent_pos) nogil
    int fcc_sparse_init(fcc_engine *e, const fcc_pattern *P) nogil
    int fcc_sparse_resize(fcc_engine *e) nogil
    void fcc_sparse_free(fcc_engine *e) nogil
    void fcc_sparse_set_beyond_rank(fcc_engine *e, double kept_sigma) noexcept nogil
    void fcc_sparse_set_watch(fcc_engine *e, int k, const double *basis,
                              double trigger) noexcept nogil
    void fcc_sp_assemble_mb(fcc_engine *e, const double *q, int flags) noexcept nogil
    int fcc_sp_factor(fcc_engine *e, const double *q) noexcept nogil
    void fcc_sp_solve_a(fcc_engine *e, double *x) noexcept nogil


cdef extern from "fcc_events.h":
    enum:
        FCC_ACT_STOP
        FCC_ACT_LOG
        FCC_ACT_LOCK
        FCC_ACT_UNLOCK
        FCC_ACT_BOUNCE
        FCC_ACT_REST
        FCC_ACT_RELEASE
        FCC_LOG_COLS
        FCC_NOTE_REDUNDANT
        FCC_NOTE_UNCERTAIN
        FCC_EVENT_ABI_VERSION

    ctypedef struct fcc_event_table:
        int abi_version
        int n_q
        int n_p
        int n_events
        int n_quantities
        void (*quantity_values)(const double *q, const double *v, double t,
                                const double *p, double *out) noexcept nogil
        void (*quantity_gradients)(const double *q, const double *v, double t,
                                   const double *p, double *out) noexcept nogil
        void (*quantity_bias)(const double *q, const double *v, double t,
                              const double *p, double *out) noexcept nogil
        int n_gradient_nz
        const int *gradient_ptr
        const int *gradient_idx
        void (*quantity_gradient_values)(const double *q, const double *v, double t,
                                         const double *p, double *out) noexcept nogil

    ctypedef struct fcc_event_spec:
        const fcc_event_table *tab
        int n, ne, nr, np, nang
        double tol
        int max_per_step
        long cap_log

    ctypedef struct fcc_events:
        const fcc_event_spec *spec
        double *p
        double *s0
        double *s1
        double *r
        double *rg
        double *rb
        int m
        double *aug
        int mz
        int stop
        long n_log
        double *log
        int nm
        double max_turn
        int max_turn_j
        int fold
        long n_fold_off
        long n_switch_solves
        int fold_trial
        long n_trials
        long n_trials_folded

    ctypedef struct fcc_bracket:
        double a, b
        double fa, fb
        int side, it

    int fcc_event_spec_init(fcc_event_spec *c, const fcc_event_table *tab, int nang,
                            const int *angle_row, const int *direction,
                            const int *action, const int *row, const int *row2,
                            const double *restitution, double tol, double v_rest,
                            int max_per_step, long cap_log) nogil
    void fcc_event_spec_free(fcc_event_spec *c) nogil
    int fcc_events_init(fcc_events *ev, const fcc_event_spec *c,
                        const double *constants) nogil
    void fcc_events_free(fcc_events *ev) nogil
    int fcc_events_rank_work(fcc_events *ev, const fcc_lapack *lapack, int m) nogil
    int fcc_events_sparse_work(fcc_events *ev, int m) nogil
    void fcc_events_reset(fcc_events *ev) nogil
    int fcc_events_fold(fcc_events *ev, fcc_engine *e, int on) nogil
    int fcc_events_mirror(fcc_events *ev, fcc_assembly *a, int n, const int *slots,
                          const int *angles) nogil
    void fcc_events_restore(fcc_events *ev) nogil
    void fcc_ev_bracket(fcc_events *ev, int k, fcc_bracket *br, double b) noexcept nogil
    int fcc_ev_bracket_open(fcc_events *ev, fcc_bracket *br, double scale) noexcept nogil
    double fcc_ev_bracket_trial(fcc_bracket *br) noexcept nogil
    void fcc_ev_bracket_update(fcc_events *ev, int k, fcc_bracket *br, double c,
                               double fc) noexcept nogil
    void fcc_ev_refresh(fcc_events *ev, const double *q) noexcept nogil
    void fcc_ev_values(fcc_events *ev, const double *q, const double *v, double t,
                       double *out) noexcept nogil
    int fcc_ev_watch(fcc_engine *e, fcc_events *ev, const double *q, const double *v,
                     double t, double *out) noexcept nogil
    int fcc_ev_crossed(fcc_events *ev, const double *a, const double *b) noexcept nogil
    int fcc_ev_watched(fcc_events *ev, int k, const double *a,
                       const double *b) noexcept nogil
    int fcc_ev_crosses(fcc_events *ev, int k, double a, double b) noexcept nogil
    int fcc_ev_constrain(fcc_engine *e, fcc_events *ev, const double *q,
                         const double *v, double t, double *a) noexcept nogil
    int fcc_ev_correct(fcc_engine *e, fcc_events *ev, double *q, double *v) noexcept nogil
    int fcc_ev_apply(fcc_engine *e, fcc_events *ev, int k, double *q, double *v,
                     double t) noexcept nogil
    double fcc_ev_leaving(fcc_events *ev, int k, const double *q, const double *v,
                          double t) noexcept nogil


cdef extern from "fcc_work.h":
    ctypedef struct fcc_power:
        fcc_assembly *nc
        int n_params, n_zero, constraints, n

    int fcc_power_init(fcc_power *w, fcc_assembly *nc, int n, const int *src,
                       int n_zero, const int *zero, int constraints) nogil
    void fcc_power_free(fcc_power *w) nogil
    int fcc_power_fits(const fcc_power *w, const fcc_engine *e) nogil
    double fcc_stage_power(fcc_engine *e, fcc_power *w, const double *q,
                           const double *v, const double *a) noexcept nogil


cdef extern from "fcc_run.h":
    ctypedef int (*fcc_pause_fn)(void *ctx) noexcept nogil
    ctypedef struct fcc_records:
        double *t
        double *q
        double *v
        double *body
        double *energy
        double *cerr


cdef extern from "fcc_sens.h":
    ctypedef struct fcc_dp_table:
        int abi_version
    ctypedef struct fcc_sens:
        int n, m, np
        double *out

    int fcc_sens_init(fcc_sens *s, const fcc_model *model, const fcc_dp_table *dp,
                      int np, const double *dP) nogil
    void fcc_sens_free(fcc_sens *s) nogil
    void fcc_sens_start(fcc_sens *s, const double *S0) nogil
    int fcc_sens_events_init(fcc_sens *s, fcc_events *ev, double *tout, long cap) nogil


cdef extern from "fcc_rk4.h":
    ctypedef struct fcc_rk4:
        int project, baumgarte
        double alpha, beta
        long n_steps, every
        double dt, t_end
        fcc_records out
        fcc_events *ev
        double *saved
        double *dense
        int on_interpolant
        fcc_pause_fn pause
        void *pause_ctx
        long k, n_out, n_rhs, newton_total
        int newton_max
        long failures
        double max_cerr
        int stopped
        double t_stop
        fcc_power *pw
        double *w_out
        double w
        fcc_sens *sens

    int fcc_rk4_start(fcc_rk4 *r, fcc_engine *e, const double *q0,
                      const double *v0) noexcept nogil
    void fcc_rk4_record(fcc_engine *e, fcc_rk4 *r, double t) noexcept nogil
    int fcc_rk4_advance(fcc_engine *e, fcc_rk4 *r) noexcept nogil
    void fcc_run_finish(fcc_engine *e) noexcept nogil


cdef extern from "fcc_sens_dopri5.h":
    ctypedef struct fcc_sens_dp5:
        fcc_sens *s
        int control
        const double *scale
        double *work


cdef extern from "fcc_dopri5.h":
    ctypedef struct fcc_dopri5:
        int project
        double rtol, atol, t_end, h0
        long n_req
        fcc_records out
        fcc_events *ev
        double *work
        fcc_pause_fn pause
        void *pause_ctx
        double t, h
        long accepted, rejected, n_rhs, newton_total, failures
        double max_cerr
        long n_out
        int stopped
        double t_stop
        fcc_power *pw
        double *w_out
        double w
        double q_bound, v_bound
        fcc_sens_dp5 sens

    int fcc_dopri5_start(fcc_dopri5 *r, fcc_engine *e, const double *q0,
                         const double *v0) noexcept nogil
    int fcc_dopri5_advance(fcc_engine *e, fcc_dopri5 *r) noexcept nogil


cdef extern from "fcc_ali3p.h":
    double FCC_ALI3P_PENALTY_RAISE

    ctypedef struct fcc_ali3p:
        long n_steps, every
        double dt, t_end, tol
        int max_newton
        int max_raises
        int raises
        double *state
        int *ipiv
        fcc_records out
        fcc_pause_fn pause
        void *pause_ctx
        long k, n_out, n_asm, newton_total
        int newton_max
        long failures, slow_steps
        double max_cerr
        int fail, fail_info, fail_detail
        double fail_t, fail_h, fail_dq
        long lu_steps

    void fcc_ali3p_start(fcc_ali3p *r, fcc_engine *e) noexcept nogil
    void fcc_ali3p_record(fcc_engine *e, fcc_ali3p *r, double t) noexcept nogil
    int fcc_ali3p_advance(fcc_engine *e, fcc_ali3p *r) noexcept nogil
