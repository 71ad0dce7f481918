/* The sparse path: element blocks, the LDL^T of A = M + B^T diag(alpha) B, the
 * augmented-Lagrangian refinement and the sparse engine's solves (fcc_sparse_*.c).
 *
 * fcc_pattern holds the constants a set-up analysis fixes once per model (the Python
 * build's fccgen.runtime.sparsity and sparse_setup; an export writes them as data):
 * the solve's view of the elements (pinned coordinates, fixed rows), the guards of
 * the entries the pattern leaves out, the fill-reducing order, the pattern of A and
 * of its factor. fcc_sparse holds one instance's work and statistics; it lives in the
 * fcc_engine that takes the sparse path. Needs no LAPACK, except for two optional
 * features (the dense fallback of an unconverged solve, the SVD check of the rank
 * watch), which a NULL table leaves out.
 */
#ifndef FCC_SPARSE_H
#define FCC_SPARSE_H

#include "fcc_assemble.h"

struct fcc_engine;

/* The rank-growth watch tracks at most this many null-space directions. */
#define FCC_TRACK_MAX 16
/* Unconverged solves are redone densely up to this many coordinates (default). */
#define FCC_DENSE_FALLBACK_MAX 1000
/* Caps of one solve's refinement (defaults; fcc_sparse.refine_max, cg_max, al_max). */
#define FCC_REFINE_MAX 3
#define FCC_CG_MAX 400
#define FCC_AL_MAX 8
/* alpha_k = FCC_RHO m_ref / s_k^2 (fcc_sparse_blocks.c says why). */
#define FCC_RHO 1e7
/* alpha's factor for the rest of a factorisation's solves once one of them turns slow
 * (fcc_al_refine.c, "Near a singular position"). */
#define FCC_AL_BOOST 1e5
/* Once a solve needed it, the next FCC_BOOST_HOLD factorisations are made with the
 * boost at once, and the count starts again while their solves stay slow. */
#define FCC_BOOST_HOLD 8
/* Directions beyond the decided rank (fcc_al_refine.c). */
#define FCC_BEYOND_FRACTION 1e-2

typedef struct fcc_pattern {
    const fcc_model *model;
    int n, m;                   /* coordinates, constraint rows */
    int *mptr, *bptr;           /* per element: start of its mass, Jacobian block */
    /* The solve's view (fcc_pattern_set_view): each element's free local coordinates
     * and kept rows, its blocks compacted to them. Without pinned coordinates the
     * full view, the compact blocks the blocks themselves. */
    int compact;
    int *snq;                   /* per element: its free local coordinates */
    int *sptr;                  /* per element: start in sidx and sloc (n_el + 1) */
    int *sidx;                  /* the global index of each free local coordinate */
    int *sloc;                  /* its place in the element's local list */
    int *sng;                   /* per element: its kept rows */
    int *sgptr;                 /* per element: start in srow and srloc (n_el + 1) */
    int *srow;                  /* the global index of each kept row */
    int *srloc;                 /* its local row */
    int *mcptr, *bcptr;         /* per element: start of its compact blocks */
    int total_mc, total_bc;
    double *efix;               /* per element: the largest norm of its fixed rows */
    int n_pinned;
    int *pinned;                /* the pinned coordinates */
    int *pin_diag;              /* where each one's diagonal sits in Ax */
    int n_fixed;                /* entries of the fixed rows' blocks */
    int *fixed_off;             /* offsets into Bblk */
    double *fixed_val;          /* their values where they were read */
    double *fixed_tol;          /* the change each may take */
    int n_fixed_rows;
    int *fixed_rows;            /* the fixed rows (global) */
    double *fixed_norm;         /* their (constant) norms */
    double *fixed_g_tol;        /* |g_k| each may reach: position_tol ||B_k|| */
    /* Entries zero where the pattern was taken (fcc_pattern_set_guards). */
    int n_zero_m, n_zero_b;
    int *zero_m, *zero_b;       /* offsets into Mblk / Bblk */
    double *zero_m_tol, *zero_b_tol;
    /* A and its factor (fcc_pattern_set_structure). */
    int ready;
    int n_lead;                 /* the leading columns the LDL^T and its solves cover */
    int nnz_a, nnz_l;
    int *perm;                  /* new -> old */
    int *Ap, *Ai;               /* upper(P A P^T), compressed columns */
    int *ent_ptr;               /* per element: start of its entries of A (n_el + 1) */
    int *ent_a, *ent_b;         /* each entry's local row and column on the view */
    int *ent_pos;               /* and its place in Ax */
    int lb_size;                /* the largest nq x ng of an element on the view */
    int *Lp, *Li, *Rp, *Rj, *Rpos;   /* the pattern of L (fcc_ldl_rows) */
    /* Switchable rows folded into A (fcc_pattern_set_switchable; fcc_sparse_fold.c):
     * rows m .. m + n_sw - 1 of the solve, each on the free coordinates it reads,
     * with its entries of A (their pairs in the pattern from the set-up on). 0: none,
     * the events' rows go through a Schur complement (fcc_events.c). */
    int n_sw;
    int *sw_ptr;                /* per row: start in sw_idx (n_sw + 1) */
    int *sw_idx;                /* the coordinates it reads */
    int *sw_ent_ptr;            /* per row: start of its entries of A (n_sw + 1) */
    int *sw_ent_a, *sw_ent_b, *sw_ent_pos;   /* local pair, place in Ax */
} fcc_pattern;

typedef struct fcc_sparse {
    const fcc_pattern *pat;
    /* blocks, A and its factor */
    double *Mblk, *Bblk;        /* the kernels' element blocks */
    double *Mc, *Bc;            /* on the solve's view (aliases without pins) */
    double *lq;                 /* an element's coordinates */
    double *alpha;              /* m: penalty per row */
    double *rnorm;              /* m: ||B_k|| of the Jacobian blocks held */
    double mref;                /* the largest diagonal entry of the mass blocks held */
    double boost;               /* alpha = boost FCC_RHO ... in the factor held (1 or
                                   FCC_AL_BOOST: fcc_sp_factor_boosted) */
    int held;                   /* an LDL^T of A is held (the last factor succeeded) */
    int tripped;                /* a guard found the pattern broken */
    double *Ax, *lb, *Lx, *Dinv, *Y;
    double *tperm;              /* n: the permuted right-hand side of a solve */
    long n_factor;
    long n_assembled;           /* assemblies of the blocks (fcc_sp_assemble_blocks) */
    long n_boosted;             /* factorisations with FCC_AL_BOOST */
    int boost_hold;             /* factorisations left to make with FCC_AL_BOOST at
                                   once (fcc_al_refine.c, "Near a singular
                                   position") */
    double slow_rate;           /* the last refinement's slowest step rate */
    int own_lam_seen;           /* the run's factors served solves with their own
                                   multipliers (sensitivities): no boost_hold */
    /* the refinement (fcc_al_refine.c) */
    double *w_n, *r1, *dx, *base, *lz;
    double *lam, *lam_warm, *r2, *bdx, *res, *mu, *cg_p, *cg_sp, *u;
    int warm_valid;
    long n_solves, n_iterations, n_unconverged, n_beyond_rank;
    double beyond_quotient;     /* the Rayleigh-quotient bound (0: off) */
    int beyond_hit;
    int most_iterations;
    int cg_max, refine_max, al_max;
    double rho;
    int cg_steps;
    double x_floor;             /* the stop tests' floor under |x| (0: none) */
    double v_peak;              /* largest max |v_i| a velocity projection met */
    /* the sparse engine (fcc_sparse_engine.c, fcc_sparse_watch.c) */
    int n_track;                /* tracked null-space directions (0: no watch) */
    double *track;              /* n x FCC_TRACK_MAX: their orthonormal basis N */
    double *bn;                 /* m x FCC_TRACK_MAX: B_s N, column by column */
    double *xw, *rs, *qsave, *mv;
    double grow_trigger;        /* the bound that starts an SVD check */
    double bound_max;           /* largest ||B_s N||_F met */
    long n_svd;
    long n_fallback, n_chord, n_chord_undone;
    int dense_fallback_max;
    /* the switchable rows folded into A (fcc_sparse_fold.c) */
    int ms;                     /* the solve's rows: m + the pattern's n_sw */
    double *sw_val;             /* per row its values on sw_idx (zero while free) */
    double *sw_tgt;             /* n_sw: their targets in the accelerations */
    const double *sw_b;         /* the targets of the solve under way (NULL: zero) */
    int sw_live;                /* some row is folded into the factor held */
    /* Fills sw_val and rnorm[m + j] at q (v NULL: at every assembly of B), or the
     * targets sw_tgt at (q, v) (the accelerations); NULL: no row folded. */
    void (*sw_fill)(void *ctx, struct fcc_engine *e, const double *q, const double *v);
    void *sw_ctx;
    /* Called (rarely: once per rank increase) to start the watch again from the null
     * space of B (fcc_sparse_set_watch); NULL: the watch stops there. */
    void (*restart_watch)(void *ctx, struct fcc_engine *e);
    void *restart_ctx;
} fcc_sparse;

/* -- the pattern (set-up) --------------------------------------------------------- */
/* The full view of the model's elements; no pins, no guards, no structure yet. */
int fcc_pattern_init(fcc_pattern *P, const fcc_model *m);
void fcc_pattern_free(fcc_pattern *P);
/* The solve's view: per element its free local coordinates sloc (snq[e] of them, in
 * order) and kept rows srloc (sng[e]); efix per element; the pinned coordinates; the
 * fixed rows with their norms and |g| tolerances; the fixed rows' block entries
 * (offsets into the Jacobian blocks, values, tolerances). */
int fcc_pattern_set_view(fcc_pattern *P, const int *snq, const int *sloc,
                         const int *sng, const int *srloc, const double *efix,
                         int n_pinned, const int *pinned, int n_fixed_rows,
                         const int *fixed_rows, const double *fixed_norm,
                         const double *fixed_g_tol, int n_fixed, const int *fixed_off,
                         const double *fixed_val, const double *fixed_tol);
/* The block entries zero where the pattern was taken, and the size each may reach. */
int fcc_pattern_set_guards(fcc_pattern *P, int n_zero_m, const int *zero_m,
                           const double *zero_m_tol, int n_zero_b, const int *zero_b,
                           const double *zero_b_tol);
/* The order (perm: new -> old), the pattern of upper(P A P^T) (Ap, Ai), each
 * element's entries of A on the view (ent_ptr over elements; ent_a, ent_b local row
 * and column; ent_pos place in Ax), and the symbolic factorisation. Returns
 * FCC_ERR_ARGUMENT when a pinned coordinate's column lacks its diagonal. */
int fcc_pattern_set_structure(fcc_pattern *P, const int *perm, const int *Ap,
                              const int *Ai, const int *ent_ptr, const int *ent_a,
                              const int *ent_b, const int *ent_pos);

/* The switchable rows folded into A (after fcc_pattern_set_structure, whose pattern
 * must hold their pairs): per row its coordinates (sw_ptr over n_sw rows, sw_idx) and
 * its entries of A (sw_ent_ptr; sw_ent_a, sw_ent_b local pair; sw_ent_pos place in
 * Ax). FCC_ERR_ARGUMENT when a coordinate or place is out of range. */
int fcc_pattern_set_switchable(fcc_pattern *P, int n_sw, const int *sw_ptr,
                               const int *sw_idx, const int *sw_ent_ptr,
                               const int *sw_ent_a, const int *sw_ent_b,
                               const int *sw_ent_pos);

/* -- the instance's work (set-up) ------------------------------------------------ */
/* Take the sparse path with the pattern P (kept by pointer: it must outlive e). */
int fcc_sparse_init(struct fcc_engine *e, const fcc_pattern *P);
/* Reallocate what depends on the pattern, after it changed (set-up). */
int fcc_sparse_resize(struct fcc_engine *e);
void fcc_sparse_free(struct fcc_engine *e);
/* Reset the statistics (a rank decision), and the watch (n_track 0). */
void fcc_sparse_reset_stats(struct fcc_engine *e);
/* Stop the conjugate-gradient corrections beyond the decided rank (kept_sigma: the
 * smallest scaled singular value kept; 0: off). */
void fcc_sparse_set_beyond_rank(struct fcc_engine *e, double kept_sigma);
/* The watch's basis (n x k, column j at track + j n) and its trigger. */
void fcc_sparse_set_watch(struct fcc_engine *e, int k, const double *basis,
                          double trigger);

/* -- blocks, A, its factor (fcc_sparse_blocks.c) --------------------------------- */
void fcc_sp_assemble_blocks(struct fcc_engine *e, const double *q, const double *v,
                            int flags);
void fcc_sp_assemble_mb(struct fcc_engine *e, const double *q, int flags);
int *fcc_sp_copy_ints(const int *src, int n);            /* fcc_sparse_pattern.c */
void fcc_sp_check_fixed_g(struct fcc_engine *e);
void fcc_sp_mult_m(struct fcc_engine *e, const double *x, double *y, int add);
void fcc_sp_mult_m_full(struct fcc_engine *e, const double *x, double *y, int add);
void fcc_sp_mult_b(struct fcc_engine *e, const double *x, double *y);
void fcc_sp_mult_bt(struct fcc_engine *e, const double *z, const double *s, double *y);
void fcc_sp_gather_dense(struct fcc_engine *e);
double fcc_sp_scaled_residual(struct fcc_engine *e);
int fcc_sp_factor(struct fcc_engine *e, const double *q);
int fcc_sp_factor_boosted(struct fcc_engine *e);
int fcc_sp_factor_unboosted(struct fcc_engine *e);
void fcc_sp_solve_a(struct fcc_engine *e, double *x);
void fcc_sp_solve_a_add(struct fcc_engine *e, const double *y, double *x, double *step,
                        double *size);
/* the switchable rows (fcc_sparse_fold.c) */
void fcc_sp_sw_fill(struct fcc_engine *e, const double *q);
void fcc_sp_sw_penalties(struct fcc_engine *e);
void fcc_sp_sw_factor(struct fcc_engine *e);
void fcc_sp_sw_mult(struct fcc_engine *e, const double *x, double *y);
void fcc_sp_sw_mult_t(struct fcc_engine *e, const double *z, const double *s,
                      double *y);
void fcc_sp_sw_residual(struct fcc_engine *e, const double *x, int pending,
                        int penalised, double *y, double *r2);
void fcc_sp_sw_first(struct fcc_engine *e, int warm, double *y);
int fcc_sp_nonfinite_input(struct fcc_engine *e, const double *q, const double *v,
                           int flags);

/* -- the refinement (fcc_al_refine.c) --------------------------------------------- */
void fcc_sp_first_pass(struct fcc_engine *e, const double *b, int warm, double *y);
int fcc_sp_kkt_solve(struct fcc_engine *e, const double *Q, const double *w,
                     const double *b, double *x, int warm, int newton);
int fcc_sp_kkt_solve_from(struct fcc_engine *e, const double *Q, const double *w,
                          const double *b, double *x, double *lam_io, int valid,
                          int newton);

/* -- the sparse engine (fcc_sparse_engine.c, fcc_sparse_watch.c) ----------------- */
int fcc_sp_accelerations(struct fcc_engine *e, const double *q, const double *v,
                         double *a, int reuse);
/* lam of the acceleration solve just made, corrected once (fcc_sparse_engine.c) */
int fcc_sp_correct_multipliers(struct fcc_engine *e, const double *r, const double *a,
                               double *lam, double *y, double *b);
int fcc_sp_baumgarte(struct fcc_engine *e, const double *q, const double *v, double *a,
                     double alpha, double beta);
void fcc_sp_assemble_constraints(struct fcc_engine *e, const double *q, int flags);
int fcc_sp_chord_ready(struct fcc_engine *e);
int fcc_sp_chord_step(struct fcc_engine *e, double *q, double *res);
void fcc_sp_solve_kkt(struct fcc_engine *e, const double *Q, const double *w,
                      const double *b, double *x, int warm, int newton);
int fcc_sp_solve_kkt_from(struct fcc_engine *e, const double *Q, double *x,
                          double *lam_io, int valid);
int fcc_sp_project_velocities(struct fcc_engine *e, const double *q, double *v,
                              int have_B);
void fcc_sp_watch_rank(struct fcc_engine *e);

#endif
