# cython: language_level=3
"""The sparse path: accelerations and projections in time linear in the model's size.

SparseEngine is an Engine (same building blocks, same integrators) whose constrained
solves are the augmented-Lagrangian refinement of _al_refine.pyx over the element
blocks and the LDL^T of A = M + B^T diag(alpha) B of _sparse_blocks.pyx:

* accelerations: M a + B^T lambda = f - h, B a = -c (Baumgarte:
  B a = -c - 2 alpha g' - beta^2 g, formed in :meth:`SparseEngine.baumgarte_targets`);
* velocity projection: M w + B^T mu = M v, B w = b with b from
  :meth:`SparseEngine.velocity_targets` (-dg/dt of time-dependent constraints);
* each Newton step of the position projection (Engine.project_positions_at, with
  this engine's assembly, residual and solve): M dq + B^T mu = 0, B dq = -g; after an
  integrator's step, first chord steps (below).

Chord steps. After an RK4 step the blocks and the factorisation held are those of its
last stage, at q + h v3, about h^2 a / 2 from the new q (5e-6 m on the cart of 20 links
at dt 1e-3; DOPRI5's last stage is at the new q itself). A Newton step with them,
M4 dq + B4^T mu = 0, B4 dq = -g(q), is a chord step: a consistent system, whose error
is B4 - B(q), relative size d (about the distance over the model's size). It is solved
by one augmented-Lagrangian step from zero multipliers, dq = A4^{-1} B4^T alpha (-g),
off by about 1 / (1 + alpha sigma^2 / m) of itself (1e-7 where the rows are well
conditioned, more near a singular position, where it shows in the residual as d does).
The step leaves about d of the residual (1e-6 .. 1e-5, measured after RK4 steps of
1e-3 s), and moves q along the constraints, where no residual sees it, by about d times
the step; its metric is M at the stage's positions instead of the new ones, a change of
the same order. It saves the factorisation, the assembly of M and B and the refined
solve of an exact step: a sixth of the cart's RK4 step at n = 20. A chord step is kept
when it leaves at most CHORD_GAIN of the residual and that move, estimated as the
fraction of the residual left times the step's largest component, is at most CHORD_DRIFT
of the position tolerance; otherwise (a factorisation made far from q, a row that nearly
vanishes there, or a large step: the double pendulum at dt 0.05, where d is about 1e-2
and the steps about 1e-7 m, moved 1.4e-8 m off the exact projections' trajectory in 20
steps) it is undone and exact steps take over. The blocks must be the factorisation's
own: B at the new q with the stage's factor makes the penalised system inconsistent by
alpha |B| |B4 - B(q)|, and the step then moves q along the constraints by about RHO d
times its size (100 times on the cart). Models with rows dependent only on the
constraint manifold (_al_refine.pyx, "Directions beyond the decided rank") take exact
steps only, whose solves fall back to the dense path's treatment of those rows.

A solve whose refinement did not converge (constraints so ill-conditioned that the
conjugate-gradient corrections run out of steps: _al_refine.pyx) is counted, and
redone by the dense path's solve (pivoted QR of B at the decided rank, _solve.pyx) on
M and B gathered from the blocks, when the model has at most DENSE_FALLBACK_MAX
coordinates; the run reports both counts and warns (fccgen.rank.run_findings).

Changes of the degrees of freedom. The solves need no rank, but the reports do: the
rank r decided at the start (fccgen.rank) is kept, and raised, as on the dense path,
when an SVD at a projected state finds sigma_{r+1} > GROW_TOL sigma_1 (rows scaled as
fccgen.rank.row_scales). What starts that SVD is a bound, not a guess: for any n x k
matrix N with orthonormal columns, k = n - r,

    sigma_{r+1}(B_s) <= ||B_s N||_2 <= ||B_s N||_F        (Courant-Fischer)

and sigma_1 >= 1 (each element's largest scaled row has unit length), so no growth
past GROW_TOL goes unseen while ||B_s N||_F stays at or below it. N tracks the null
space of B: set from the SVD at the start, then at every velocity projection replaced
by A^{-1} M N (orthonormalised) with the factor at hand: a null-space direction is kept
exactly (A x = M x when B x = 0), a component along a row direction of singular value
sigma shrinks by about 1 / (1 + RHO sigma^2), so the motion of the constraint manifold
between steps leaves ||B_s N|| near 1e-10 while a new independent row (sigma_{r+1}
leaving 0) shows in full. One extra solve with A per tracked direction and projection.
An SVD that does not confirm growth, finding sigma_{r+1} = x sigma_1 (x <= GROW_TOL),
moves the trigger to the bound times GROW_TOL / x, kept within [2, 10]: the next SVD
comes when the bound has grown as much as sigma_{r+1} must to pass GROW_TOL (the bound
follows sigma_{r+1} within a constant on a mechanism leaving a singular position),
at least twice, so that SVDs stay rare near singular positions, and at most ten
times (the dense path's rule for its pivot).
"""
from libc.math cimport INFINITY, sqrt
from libc.stdlib cimport free
from libc.string cimport memcpy, memset

import numpy as np

from fccgen import rank as rank_rule

from .sparsity import jacobian_csr

from ._al_refine cimport ALRefinement
from ._cengine cimport fcc_assemble, fcc_put_time, fcc_max_abs_g, fcc_scaled_residual
from ._assemble cimport ASM_B, ASM_C, ASM_F, ASM_G, ASM_H, ASM_M, ASM_T
from ._engine cimport (ERR_NONFINITE_INPUT, ERR_NONFINITE_RESULT, Engine,
                       RANK_LOG_SIZE, finite)
from ._solve cimport csolve_apply, csolve_factor, csolve_svd_rank
from ._sparse_blocks cimport alloc_zeroed

# An unconverged solve is redone densely up to this many coordinates: the dense
# factorisation is O(n^3), about 60 ms at 483 coordinates (A02, N = 160: 310 ms per
# dense RK4 step of five), 0.5 s at 1000, acceptable for the rare evaluation that
# needs it; larger models keep the unconverged solve and warn.
DEF DENSE_FALLBACK_MAX = 1000
# The rank-growth watch tracks at most this many null-space directions (degrees of
# freedom); models with more degrees of freedom and redundant rows keep the start's rank.
DEF TRACK_MAX = 16
# sigma_{r+1} > GROW_TOL sigma_1 raises the rank (fccgen.rank.GROW_TOL, the dense rule).
cdef double GROW_TOL = rank_rule.GROW_TOL
# A tracked direction whose length falls below this in the orthonormalisation has been
# taken by the constraints: check at once.
cdef double COLLAPSE = 1e-6
# A chord step is kept when it leaves at most CHORD_GAIN of the residual and moves q
# along the constraints by at most CHORD_DRIFT of the position tolerance (module
# docstring, "Chord steps"): far below what the tolerance lets through, while an RK4
# step at dt 1e-3 leaves a move of about 1e-5 of 1e-11 m.
cdef double CHORD_GAIN = 1e-2
cdef double CHORD_DRIFT = 1e-3


cdef inline double next_check_factor(double x) noexcept nogil:
    """The factor between the bound of an SVD check that found sigma_{r+1} = x sigma_1
    (below GROW_TOL) and the bound that starts the next one: GROW_TOL / x in [2, 10]."""
    if not x > 0.0 or GROW_TOL / x > 10.0:
        return 10.0
    return GROW_TOL / x if GROW_TOL / x > 2.0 else 2.0


cdef class SparseEngine(ALRefinement):
    """An Engine whose solves use the sparse augmented-Lagrangian refinement (module
    docstring). Call :meth:`set_structure` (fccgen.runtime.sparsity) before use."""
    cdef int n_track                  # tracked null-space directions (0: no watch)
    cdef double *track                # n x TRACK_MAX: their orthonormal basis N
    cdef double *bn                   # m x TRACK_MAX: B_s N, column by column
    cdef double *xw                   # n: work
    cdef double *rs                   # m: 1 / the scaled row norms
    cdef double grow_trigger          # the bound that starts an SVD check
    cdef double bound_max             # largest ||B_s N||_F met
    cdef long n_svd
    cdef object start_key             # (rank, q bytes) of the basis in start_basis
    cdef object start_basis           # the watch's basis from the SVD at that start
    cdef int start_n_track
    cdef long n_fallback              # unconverged solves redone by the dense solve
    cdef long n_chord, n_chord_undone # chord steps kept, undone
    cdef double *qsave                # n: q before a chord step
    cdef double *mv                   # n: M v of the velocity projection
    cdef readonly int dense_fallback_max

    def __cinit__(self, *args, **kwargs):
        self.track = <double *>alloc_zeroed(self.n * TRACK_MAX, sizeof(double))
        self.bn = <double *>alloc_zeroed(self.m * TRACK_MAX, sizeof(double))
        self.xw = <double *>alloc_zeroed(self.n, sizeof(double))
        self.rs = <double *>alloc_zeroed(self.m, sizeof(double))
        self.mv = <double *>alloc_zeroed(self.n, sizeof(double))
        self.qsave = <double *>alloc_zeroed(self.n, sizeof(double))
        self.dense_fallback_max = DENSE_FALLBACK_MAX

    def __dealloc__(self):
        free(self.track); free(self.bn); free(self.xw); free(self.rs); free(self.mv)
        free(self.qsave)

    def decide_rank(self, q, rank):
        """Keep the decision for the reports (the solve itself needs no rank), start
        the statistics anew, and start the rank-growth watch (module docstring) from
        the null space of the row-scaled B at q when the rank can grow (rank below
        min(n, m)) and n - rank <= TRACK_MAX; deciding again at the same q and rank
        (a run from its initial state) reuses that start's basis instead of a new SVD."""
        cdef double[::1] saved
        Engine.decide_rank(self, q, rank)
        self.n_factor = self.n_solves = self.n_iterations = self.n_unconverged = 0
        self.n_beyond_rank = 0
        self.n_fallback = 0
        self.n_chord = self.n_chord_undone = 0
        self.sol.n_drop = 0
        self.most_iterations = 0
        self.n_svd = 0
        self.bound_max = 0.0
        self.n_track = 0
        if q is None:
            return
        key = (rank, np.asarray(q, dtype=float).tobytes())
        if key != self.start_key:           # a run decides again at its initial state
            self.start_key = None
            self.start_watch(self.asm.quantity(ASM_B, q)
                             if self.n <= rank_rule.dense_columns_max() else
                             jacobian_csr(self.asm, q), rank)
            self.start_basis = np.array(<double[:self.n * TRACK_MAX]>self.track)
            self.start_n_track = self.n_track
            self.start_key = key
        else:
            saved = self.start_basis
            memcpy(self.track, &saved[0], <size_t>self.n * TRACK_MAX * sizeof(double))
            self.grow_trigger = GROW_TOL
            self.n_track = self.start_n_track

    def accelerations(self, q, v):
        """Engine.accelerations, from zero multipliers (a direct call does not depend
        on what was solved before)."""
        self.reset_warm_start()
        return Engine.accelerations(self, q, v)

    def baumgarte_accelerations(self, q, v, double alpha, double beta):
        """Engine.baumgarte_accelerations, from zero multipliers."""
        self.reset_warm_start()
        return Engine.baumgarte_accelerations(self, q, v, alpha, beta)

    def set_dense_fallback_max(self, int n_max):
        """Redo unconverged solves densely only for models of at most n_max
        coordinates (default DENSE_FALLBACK_MAX; 0: never), for tests."""
        self.dense_fallback_max = n_max

    def rank_statistics(self):
        """As Engine.rank_statistics; drops are the dense fallback's factorisations
        with a pivot dropped within the decided rank (the dense path's meaning),
        largest_dropped the largest bound ||B_s N||_F on sigma_{r+1} / sigma_1 met by
        the rank-growth watch; sparse_solves, sparse_unconverged (refinements that
        did not converge), sparse_dense_fallbacks (of those, redone densely) and
        sparse_beyond_rank (of those, stopped at a direction beyond the decided rank:
        _al_refine.pyx); chord_steps and chord_steps_undone, the position projection's
        chord steps kept and undone (module docstring)."""
        stats = Engine.rank_statistics(self)
        stats.update(factorisations=self.n_factor, drops=self.sol.n_drop,
                     svd_checks=self.n_svd, smallest_kept=1.0,
                     largest_dropped=self.bound_max, sparse_solves=self.n_solves,
                     sparse_unconverged=self.n_unconverged,
                     sparse_dense_fallbacks=self.n_fallback,
                     sparse_beyond_rank=self.n_beyond_rank, chord_steps=self.n_chord,
                     chord_steps_undone=self.n_chord_undone)
        return stats

    cdef int finish(self, const double *q, const double *v, const double *a,
                    int flags) noexcept nogil:
        """0, or the error of a non-finite result (blaming an input first)."""
        cdef int i
        if finite(a, self.n):
            return 0
        i = self.nonfinite_input(q, v, flags)
        return self.fail(ERR_NONFINITE_INPUT if i else ERR_NONFINITE_RESULT, 0, i)

    cdef int accelerations_at(self, const double *q, const double *v, double *a,
                              bint reuse) noexcept nogil:
        cdef int i, flags = ASM_H | ASM_F | ASM_C
        if reuse:
            fcc_assemble(&self.asm.a, q, v, flags)
        else:
            flags |= ASM_M | ASM_B
            self.assemble_blocks(q, v, flags)
            if self.factor(q) < 0:
                return -1
        for i in range(self.n):
            self.rhs[i] = self.asm.a.f[i] - self.asm.a.h[i]
        for i in range(self.m):
            self.nb[i] = -self.asm.a.c[i]
        self.solve_kkt(self.rhs, NULL, self.nb, a, True, False)
        return self.finish(q, v, a, flags)

    cdef int baumgarte_at(self, const double *q, const double *v, double *a,
                          double alpha, double beta) noexcept nogil:
        cdef int i, flags = ASM_M | ASM_B | ASM_H | ASM_F | ASM_C | ASM_G
        fcc_assemble(&self.asm.a, q, v, ASM_H | ASM_F | ASM_C | ASM_G
                          | (ASM_T if self.asm.model.n_time else 0))
        self.assemble_mb(q, ASM_M | ASM_B)
        if self.factor(q) < 0:
            return -1
        for i in range(self.n):
            self.rhs[i] = self.asm.a.f[i] - self.asm.a.h[i]
        self.baumgarte_targets(v, alpha, beta, self.nb)
        self.solve_kkt(self.rhs, NULL, self.nb, a, True, False)
        return self.finish(q, v, a, flags)

    cdef void baumgarte_targets(self, const double *v, double alpha, double beta,
                                double *b) noexcept nogil:
        """b = -c - 2 alpha g' - beta^2 g, the right-hand side of B a = b in
        Baumgarte's stabilisation, with g' = B v + dg/dt (assembled c, g and, for
        time-dependent constraints, dg/dt; blocks of B)."""
        cdef int i
        self.mult_b(v, b)
        if self.asm.model.n_time:
            for i in range(self.m):
                b[i] += self.asm.a.gt[i]
        for i in range(self.m):
            b[i] = -self.asm.a.c[i] - 2.0 * alpha * b[i] - beta * beta * self.asm.a.g[i]

    # -- the varying parts of Engine.project_positions_at ---------------------------
    cdef void assemble_constraints(self, const double *q, int flags) noexcept nogil:
        """g into the assembler (the fixed rows checked: SparseBlocks.set_pinned),
        M and B as element blocks."""
        if flags & ASM_G:
            fcc_assemble(&self.asm.a, q, NULL, ASM_G)
            self.check_fixed_g()
        if flags & (ASM_M | ASM_B):
            self.assemble_mb(q, flags & (ASM_M | ASM_B))

    cdef double constraint_residual(self) noexcept nogil:
        return self.scaled_residual_sparse()

    cdef bint chord_ready(self) noexcept nogil:
        """A factorisation is held, its blocks with it, and no row is dependent only on
        the constraint manifold (module docstring, "Chord steps")."""
        return self.held and not self.tripped and self.beyond_quotient == 0.0

    cdef int chord_step(self, double *q, double *res) noexcept nogil:
        """A Newton step with the blocks and factorisation held (one augmented-
        Lagrangian step: module docstring, "Chord steps"), kept (1) when it
        leaves at most CHORD_GAIN of the residual and its estimated move along the
        constraints, (residual left / residual before) max |dq|, is at most
        CHORD_DRIFT of the position tolerance; else undone (0)."""
        cdef int i, n = self.n
        cdef double trial, step, size
        for i in range(self.m):
            self.nb[i] = -self.asm.a.g[i]
        memset(self.base, 0, <size_t>n * sizeof(double))
        self.first_pass(self.nb, False, self.dq)   # B^T alpha (-g): zero where pinned
        memcpy(self.qsave, q, <size_t>n * sizeof(double))
        self.solve_a_add(self.dq, q, &step, &size)
        self.assemble_constraints(q, ASM_G)
        trial = self.constraint_residual()
        if (trial <= CHORD_GAIN * res[0]
                and trial * step <= CHORD_DRIFT * self.position_tol * res[0]):
            res[0] = trial
            self.n_chord += 1
            return 1
        memcpy(q, self.qsave, <size_t>n * sizeof(double))
        self.assemble_constraints(q, ASM_G)
        self.n_chord_undone += 1
        return 0

    cdef void solve_constrained(self, const double *Q, const double *w, const double *b,
                                double *x) noexcept nogil:
        """solve_kkt, started from zero multipliers (projections)."""
        self.solve_kkt(Q, w, b, x, False, False)

    cdef void solve_newton(self, const double *b, double *x) noexcept nogil:
        """solve_kkt of a Newton step (_al_refine.pyx, NEWTON_STOP)."""
        self.solve_kkt(NULL, NULL, b, x, False, True)

    cdef void solve_kkt(self, const double *Q, const double *w, const double *b,
                        double *x, bint warm, bint newton) noexcept nogil:
        """kkt_solve (warm: from the last accelerations' multipliers; newton: a Newton
        step's); when it did not converge, the dense solve instead (module docstring)
        if the model is small enough and M, B factor there."""
        if (self.kkt_solve(Q, w, b, x, warm, newton)
                or self.n > self.dense_fallback_max):
            return
        self.gather_dense()
        if csolve_factor(&self.sol, self.asm.a.M, self.asm.a.B) == 0:
            csolve_apply(&self.sol, Q, w, b, x)
            self.n_fallback += 1

    cdef int project_velocities_at(self, const double *q, double *v,
                                   bint have_B) noexcept nogil:
        self.assemble_mb(q, ASM_M if have_B else ASM_M | ASM_B)
        if self.factor(q) < 0:
            return -1
        self.velocity_targets(q, self.nb)
        if self.pinned_still(v):                # M v on the view is enough
            self.mult_m(v, self.mv, False)
        else:                                   # M v whole: v moves pinned coordinates
            self.mult_m_full(v, self.mv, False)
        self.solve_constrained(self.mv, NULL, self.nb, self.vtmp)
        if self.finish(q, v, self.vtmp, ASM_M | ASM_B) < 0:
            return -1
        self.watch_kinetic_energy(v, self.vtmp)
        memcpy(v, self.vtmp, self.n * sizeof(double))
        self.factor_valid = True
        self.watch_rank()
        return 0

    cdef void watch_rank(self) noexcept nogil:
        """The rank-growth watch at a projected state, with A factored there (module
        docstring): N <- orth(A^{-1} M N), then an SVD check when ||B_s N||_F passes
        the trigger."""
        cdef int i, j, k = self.n_track, n = self.n
        cdef double bound = 0.0
        cdef double *col
        cdef bint collapsed
        if k <= 0:
            return
        for j in range(k):
            col = self.track + j * n
            self.mult_m(col, self.xw, False)
            self.solve_a(self.xw)
            memcpy(col, self.xw, <size_t>n * sizeof(double))
        collapsed = not self.orthonormalise()
        if collapsed:
            bound = INFINITY
        else:
            self.scaled_rows()
            for j in range(k):
                self.mult_b(self.track + j * n, self.bn + j * self.m)
                for i in range(self.m):
                    self.bn[j * self.m + i] *= self.rs[i]
                    bound += self.bn[j * self.m + i] * self.bn[j * self.m + i]
            bound = sqrt(bound)
        if bound > self.bound_max:
            self.bound_max = bound
        if bound > self.grow_trigger:
            self.check_growth(bound, collapsed)

    cdef bint orthonormalise(self) noexcept nogil:
        """Modified Gram-Schmidt, twice, on the tracked columns; False when one of them
        shrinks below COLLAPSE of its length (the constraints took that direction)."""
        cdef int j, l, i, sweep, n = self.n
        cdef double d, before, after
        cdef double *a
        cdef double *b
        for j in range(self.n_track):
            a = self.track + j * n
            before = 0.0
            for i in range(n):
                before += a[i] * a[i]
            for sweep in range(2):
                for l in range(j):
                    b = self.track + l * n
                    d = 0.0
                    for i in range(n):
                        d += a[i] * b[i]
                    for i in range(n):
                        a[i] -= d * b[i]
            after = 0.0
            for i in range(n):
                after += a[i] * a[i]
            if not after > COLLAPSE * COLLAPSE * before:
                return False
            after = 1.0 / sqrt(after)
            for i in range(n):
                a[i] *= after
        return True

    cdef void scaled_rows(self) noexcept nogil:
        """rs_k = 1 / max(||B_k||, ROW_FLOOR * the largest row of B_k's element), the
        row scaling of fccgen.rank, from alpha_k = RHO m_ref / s_k^2 of the factor."""
        cdef int k
        cdef double largest = 0.0
        for k in range(self.m):
            if self.alpha[k] > largest:
                largest = self.alpha[k]
        for k in range(self.m):             # alpha_k / largest = (s_min / s_k)^2
            self.rs[k] = sqrt(self.alpha[k] / largest) if largest > 0.0 else 1.0
        largest = 0.0
        for k in range(self.m):
            if self.rnorm[k] * self.rs[k] > largest:
                largest = self.rnorm[k] * self.rs[k]
        for k in range(self.m):
            self.rs[k] = self.rs[k] / largest if largest > 0.0 else 1.0

    cdef void check_growth(self, double bound, bint collapsed) noexcept nogil:
        """The dense path's confirmation: the SVD of the row-scaled B (csolve_svd_rank,
        the same scaling and GROW_TOL); more singular values above GROW_TOL sigma_1
        than the decided rank raise it, logged with the time like Engine.factor, and
        the watch starts again from the null space there (also after a collapse);
        otherwise the trigger moves up (next_check_factor)."""
        cdef int e, r, a, nq, row, svd, old = self.sol.rank_fixed, n = self.n
        cdef const int *idx
        cdef const double *blk
        self.n_svd += 1
        memset(self.sol.A, 0, <size_t>self.m * n * sizeof(double))
        for e in range(self.asm.n_el):      # dense B (m x n, row-major) from the blocks
            nq = self.asm.model.cls[e].n_q
            idx = self.asm.model.qidx + self.asm.model.qptr[e]
            blk = self.Bblk + self.bptr[e]
            row = self.asm.model.gptr[e]
            for r in range(self.asm.model.cls[e].n_g):
                for a in range(nq):
                    self.sol.A[(row + r) * n + idx[a]] = blk[r * nq + a]
        svd = csolve_svd_rank(&self.sol, self.sol.A, GROW_TOL)
        if svd > old:
            if self.n_rank_log < RANK_LOG_SIZE:
                self.rank_log[self.n_rank_log][0] = self.err_t
                self.rank_log[self.n_rank_log][1] = old
                self.rank_log[self.n_rank_log][2] = svd
            self.n_rank_log += 1
            self.sol.rank_fixed = svd
        elif not collapsed:
            self.grow_trigger = bound * next_check_factor(
                self.sol.sigma[old] / self.sol.sigma[0]
                if old < min(n, self.m) and self.sol.sigma[0] > 0.0 else 0.0)
            return
        with gil:                           # rare: once per change of the rank
            self.start_watch(np.array(<double[:self.m * n]>self.sol.A).reshape(self.m, n),
                             self.sol.rank_fixed)

    def start_watch(self, B, int rank):
        """N = the right singular vectors of the row-scaled B beyond the first rank
        (its null space when rank is B's), when the rank can grow (rank below
        min(n, m)) and n - rank <= TRACK_MAX; otherwise no watch. B dense: a full SVD;
        B sparse (models above rank.dense_columns_max() coordinates, where that SVD
        would take minutes): shift-invert Lanczos on B^T B
        (fccgen.rank_sparse.smallest_right_vectors)."""
        cdef int k = self.n - rank, i, j
        self.n_track = 0
        self.grow_trigger = GROW_TOL
        if rank < 0 or rank >= min(self.n, self.m) or k > TRACK_MAX:
            return
        groups = [self.sol.group[i] for i in range(self.m)]
        try:
            if isinstance(B, np.ndarray):
                _, _, vt = np.linalg.svd(B / rank_rule.row_scales(B, groups)[:, None],
                                         full_matrices=self.m < self.n)   # vt: n x n
                basis = vt[rank:rank + k].T
            else:
                from fccgen import rank_sparse
                basis = rank_sparse.smallest_right_vectors(
                    rank_sparse.scaled(B, groups), k)
        except (np.linalg.LinAlgError, ArithmeticError, RuntimeError):
            return                           # no basis: the start's rank is kept
        for j in range(k):
            for i in range(self.n):
                self.track[j * self.n + i] = basis[i, j]
        self.n_track = k

    cdef void velocity_targets(self, const double *q, double *b) noexcept nogil:
        """b of the velocity projection's B w = b: -dg/dt at the time set last
        (zero when no constraint depends on time)."""
        cdef int i
        if not self.asm.model.n_time:
            memset(b, 0, <size_t>self.m * sizeof(double))
            return
        fcc_assemble(&self.asm.a, q, NULL, ASM_T)
        for i in range(self.m):
            b[i] = -self.asm.a.gt[i]

    cdef bint pinned_still(self, const double *v) noexcept nogil:
        """v is zero on every pinned coordinate (as after a projection): then the
        products with M on the solve's view give M v on the free coordinates, all that
        the velocity projection's solve and energy watch read (w is zero there too)."""
        cdef int i
        for i in range(self.n_pinned):
            if v[self.pinned[i]] != 0.0:
                return False
        return True

    cdef void watch_kinetic_energy(self, const double *v, const double *w) noexcept nogil:
        """As Engine.watch_kinetic_energy, with M v from the velocity projection (mv).
        The energy removed is (v - w)^T M (v - w) = (v - w)^T M v - w^T B^T mu, and
        B w = 0 when no constraint depends on time: then one product, M v, gives both
        numbers (w^T M (v - w) is rounding, about 1e-16 |w| |M (v - w)|); with
        time-dependent constraints, a second product with v - w."""
        cdef int i, n = self.n
        cdef double before = 0.0, cut = 0.0
        for i in range(n):
            self.dx[i] = v[i] - w[i]
            before += v[i] * self.mv[i]
        if self.asm.model.n_time:
            self.mult_m_full(self.dx, self.t, False)
            for i in range(n):
                cut += self.dx[i] * self.t[i]
        else:
            for i in range(n):
                cut += self.dx[i] * self.mv[i]
        if before > self.ke_peak:
            self.ke_peak = before
        if before > 1e-6 * self.ke_peak and before > 0.0 and cut / before > self.ke_cut_max:
            self.ke_cut_max = cut / before
            self.ke_cut_t = self.err_t

    cdef dict error_record(self):
        rec = Engine.error_record(self)
        rank = self.sol.rank_fixed
        rec.update(rank=rank, nullity=self.n - rank if rank >= 0 else self.n, sparse=True)
        return rec

