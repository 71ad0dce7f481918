# cython: language_level=3
"""The sparse path's constrained solve: iterative refinement of the saddle-point system

    M x + B^T lambda = Q,    B x = b

with the true residuals r1 = Q - M x - B^T lambda, r2 = b - B x, each correction an
augmented-Lagrangian step (Garcia de Jalon and Bayo) with the factor of
A = M + B^T diag(alpha) B (_sparse_blocks.pyx):

    A dx = r1 + B^T alpha r2,   dlambda = alpha (B dx - r2),

which zeroes r1 and multiplies the constraint part of the error by about
1 / (1 + alpha sigma^2 / m) (sigma: a singular value of B, m a mass): with
alpha_k = RHO m_ref / ||B_k||^2 about three iterations reach rounding. It stops when
the estimated remaining change, |dx| rate / (1 - rate), is below AL_STOP |x|. The
multiplier update alpha (B dx - r2) equals -alpha r2 at the new x, so it is made in the
next iteration's residual pass, which forms r2, the update and r1 + B^T alpha r2 in one
sweep over the element blocks. Near a singular position (sigma small) these steps slow
down; the corrections are then conjugate-gradient solves of the multipliers' Schur
system B A^{-1} B^T, preconditioned by diag(alpha): its eigenvalues are
t / (1 + t), t = alpha sigma^2 / m, clustered at 1 but for the weak directions, so a
few weak directions cost a few extra steps (the scissor mast: 2-4), many at once
more (the A02 chain of 80 loops at its flat position: 180). Their stopping test is on
the residual, with a bound set from the first step's (see the constants). Redundant
rows need no rank decision.
"""
from libc.math cimport fabs
from libc.stdlib cimport free
from libc.string cimport memcpy, memset

import numpy as np

from ._cengine cimport fcc_assemble, fcc_put_time, fcc_max_abs_g, fcc_scaled_residual
from ._assemble cimport ASM_B, ASM_M, Assembler
from ._sparse_blocks cimport SparseBlocks, alloc_zeroed
from ._sparse_blocks import PENALTY

# Augmented-Lagrangian steps stop when the estimated remaining change,
# |dx| rate / (1 - rate), is at most AL_STOP |x|; a step with rate above SLOW (or the
# AL_MAX-th) hands over to conjugate-gradient corrections. Their iterations stop when
# the preconditioned residual r2^T diag(alpha) r2 of the constraints is at most CG_TOL^2
# times its value after the first augmented-Lagrangian step (a test on the residual,
# not on the change: past the rounding floor the change can grow, along the null space
# of B^T, which the redundant rows make large), or after CG_MAX steps. The refinement
# ends when a correction after the first starts below that bound (its right-hand side
# is rounding: nothing left for the iterations) or changes x by at most
# REFINE_STOP |x|; after REFINE_MAX corrections it is a solve that did not converge
# (counted, and redone by the dense solve when the model is small enough: _sparse.pyx).
# The bound is relative to the first step's residual, not to the first correction's:
# after AL_MAX steps that converged slowly the correction may start at rounding
# already (the scissor mast of 17 bays at t = 0.2 s), and iterations below it only
# amplify the noise. CG_TOL 1e-8: measured on the A02 chain of 80 loops at its flat
# position, 1e-9 reaches the same accuracy and 1e-10 no longer converges. CG_MAX 400:
# that chain takes 180 steps there (80 eigenvalues of diag(alpha) B A^{-1} B^T spread
# between 1e-10 and 0.99: every loop's row nearly dependent).
cdef double AL_STOP = 1e-15
# A Newton step of the position projection stops at NEWTON_STOP instead (kkt_solve's
# newton): an error e |dq| in the step leaves about e times the residual it removes,
# and moves q by e |dq| along the constraints, with |dq| about the position tolerance
# (1e-11 of the model's size); the next residual check judges the step. Where the
# rows are well conditioned the second step's estimate is about 1e-14 |x|, so these
# solves take two steps instead of three.
cdef double NEWTON_STOP = 1e-8
cdef int AL_MAX = 8
cdef double SLOW = 0.05
cdef double CG_TOL = 1e-8
cdef int CG_MAX = 400
cdef double REFINE_STOP = 1e-14
cdef int REFINE_MAX = 3
# Directions beyond the decided rank (set_beyond_rank). Rows dependent only on the
# constraint manifold (a linkage mobile by its geometry: Bricard's loop, the scissor
# mast) are independent a little off it: at an RK stage, positions off by the step's
# error, their singular value rises from 1e-15 to about that error, and so does the
# right-hand side's component along them. Exactly dependent rows (A02's planar rows)
# stay dependent. The dense path keeps rank pivots and drops the rest; resolving such
# a direction instead divides the one small number by the other: stage accelerations
# wrong by O(1) (measured 9.6 and 2e4 on Bricard's two encodings at dt 1e-3) that pass
# every residual test. So for such models the conjugate-gradient corrections stop at
# a search direction p whose preconditioned Rayleigh
# quotient p^T S p / p^T diag(alpha)^-1 p, about t / (1 + t) with
# t = alpha sigma^2 / m, is below that of a direction of BEYOND_FRACTION times the
# smallest scaled singular value kept by the rank decision: far below every direction
# within the rank (the scissor mast's weakest has t = 42), far above the stage's
# (sigma ~1e-6 at dt 1e-3, 1e-4 at 1e-2, against 0.05 .. 0.2 kept on Bricard), and
# the solve counts as not converged: the dense solve, which drops that direction,
# redoes it (_sparse.pyx). Accepting the stopped solve is not enough: the
# augmented-Lagrangian steps before it move x along the direction too, by t / (1 + t)
# of the wrong amount each (Bricard's line encoding kept 1e-2 J of energy error so).
BEYOND_FRACTION = 1e-2
# Warm start. Each augmented-Lagrangian step multiplies the multipliers' error by the
# rate, about 1e-7 (RHO); from zero the first x is off by that rate times lambda, so a
# solve takes three steps (two to reach rounding, one whose rate shows it has). The
# accelerations of consecutive evaluations (RK stages, steps) differ by O(h), so
# starting from the last converged ones leaves the first x off by the rate times that
# change: two steps. Projections and Newton steps solve other systems and start from
# zero. A warm start that meets a slow step (rate above SLOW) is dropped and the solve
# starts again from zero, so the conjugate-gradient corrections near singular
# positions run exactly as from a cold start.


cdef class ALRefinement(SparseBlocks):
    """SparseBlocks with the refinement's solve :meth:`kkt_solve` (module docstring)."""

    def __cinit__(self, Assembler asm, *args, **kwargs):
        cdef int n = asm.n_q, m = asm.n_g
        self.lam = <double *>alloc_zeroed(m, sizeof(double))
        self.lam_warm = <double *>alloc_zeroed(m, sizeof(double))
        self.r2 = <double *>alloc_zeroed(m, sizeof(double))
        self.bdx = <double *>alloc_zeroed(m, sizeof(double))
        self.res = <double *>alloc_zeroed(m, sizeof(double))
        self.mu = <double *>alloc_zeroed(m, sizeof(double))
        self.p = <double *>alloc_zeroed(m, sizeof(double))
        self.sp = <double *>alloc_zeroed(m, sizeof(double))
        self.u = <double *>alloc_zeroed(n, sizeof(double))
        self.w_n = <double *>alloc_zeroed(n, sizeof(double))
        self.r1 = <double *>alloc_zeroed(n, sizeof(double))
        self.dx = <double *>alloc_zeroed(n, sizeof(double))
        self.base = <double *>alloc_zeroed(n, sizeof(double))
        self.lz = <double *>alloc_zeroed(max([asm.model.cls[e].n_g for e in range(asm.n_el)]
                                             + [1]), sizeof(double))
        self.cg_max = CG_MAX
        self.refine_max = REFINE_MAX
        self.al_max = AL_MAX

    def __dealloc__(self):
        free(self.lam); free(self.lam_warm); free(self.r2); free(self.bdx); free(self.res)
        free(self.mu); free(self.p); free(self.sp); free(self.u); free(self.w_n)
        free(self.r1); free(self.dx); free(self.base); free(self.lz)

    def limit_refinement(self, int corrections=REFINE_MAX, int cg_steps=CG_MAX,
                         int al_steps=AL_MAX):
        """Cap the corrections, conjugate-gradient steps and augmented-Lagrangian
        steps of a solve (defaults: the module's REFINE_MAX, CG_MAX, AL_MAX); low caps
        make solves stop unconverged, for tests of what follows."""
        if corrections < 1 or cg_steps < 0 or al_steps < 1:
            raise ValueError("at least one correction and one augmented-Lagrangian "
                             "step, and no negative step count")
        self.refine_max = corrections
        self.cg_max = cg_steps
        self.al_max = al_steps

    def set_beyond_rank(self, double kept_sigma):
        """Stop the conjugate-gradient corrections at directions beyond the decided
        rank (module constants, "Directions beyond the decided rank"): kept_sigma is
        the smallest scaled singular value the rank decision kept (sigma_r /
        sigma_1); 0 turns the stop off (rows dependent exactly, or none)."""
        cdef double t = PENALTY * (BEYOND_FRACTION * kept_sigma) ** 2
        self.beyond_quotient = t / (1.0 + t) if kept_sigma > 0.0 else 0.0

    @property
    def beyond_rank_quotient(self):
        """The Rayleigh quotient below which the corrections stop (0: off)."""
        return self.beyond_quotient

    def solve_statistics(self):
        """Factorisations and solves since the last rank decision, refinement iterations
        in all and at most in one solve, and solves that did not converge."""
        return dict(factorisations=self.n_factor, solves=self.n_solves,
                    iterations=self.n_iterations, max_iterations=self.most_iterations,
                    unconverged=self.n_unconverged, beyond_rank_stops=self.n_beyond_rank)

    cdef void residual_pass(self, const double *x, const double *b, bint pending,
                            bint penalised, double *y, double *r2) noexcept nogil:
        """One pass over the elements for the true residuals at x:
        r2 = b - B x (b NULL: zero; stored when r2 is not NULL), then, when pending,
        the deferred multiplier update lambda -= alpha r2 (the augmented-Lagrangian
        update lambda + alpha (B dx - r2_old) written with the new residual), and
        y = base - M x - B^T (lambda - alpha r2) when penalised (the right-hand side
        r1 + B^T alpha r2 of the next correction), y = r1 = base - M x - B^T lambda
        otherwise; rho = r2^T diag(alpha) r2. Each element's coordinates are gathered
        and scattered once; each of its coordinates' share is summed in a register
        (M row, then the rows' terms in order), not through memory."""
        cdef int e, a, c, r, nq, ng, row
        cdef const int *idx
        cdef const int *rows
        cdef const double *mb
        cdef const double *bb
        cdef double *xl = self.lq
        cdef double *zl = self.lz
        cdef double acc, z
        memcpy(y, self.base, <size_t>self.n * sizeof(double))
        self.rho = 0.0
        for e in range(self.asm.n_el):
            nq = self.snq[e]
            ng = self.sng[e]
            mb = self.Mc + self.mcptr[e] if self.mcptr[e + 1] > self.mcptr[e] else NULL
            if mb == NULL and ng == 0:
                continue
            idx = self.sidx + self.sptr[e]
            for a in range(nq):
                xl[a] = x[idx[a]]
            bb = self.Bc + self.bcptr[e]
            rows = self.srow + self.sgptr[e]
            for r in range(ng):
                row = rows[r]
                acc = b[row] if b != NULL else 0.0
                for a in range(nq):
                    acc -= bb[r * nq + a] * xl[a]
                if pending:
                    self.lam[row] -= self.alpha[row] * acc
                if r2 != NULL:
                    r2[row] = acc
                self.rho += acc * self.alpha[row] * acc
                z = self.lam[row]
                if penalised:
                    z -= self.alpha[row] * acc
                zl[r] = z
            for a in range(nq):
                acc = 0.0
                if mb != NULL:
                    for c in range(nq):
                        acc += mb[a * nq + c] * xl[c]
                for r in range(ng):
                    acc += bb[r * nq + a] * zl[r]
                y[idx[a]] -= acc

    cdef void first_pass(self, const double *b, bint warm, double *y) noexcept nogil:
        """residual_pass at x = 0 (not pending, penalised), with lambda = 0 or (warm)
        the multipliers kkt_solve started from: y = base - B^T (lambda - alpha b),
        without the products with M and B that vanish there; the same operations in
        the same order as residual_pass on what is left (the same rounding)."""
        cdef int e, a, r, nq, ng, row
        cdef const int *idx
        cdef const int *rows
        cdef const double *bb
        cdef double *zl = self.lz
        cdef double acc, z
        memcpy(y, self.base, <size_t>self.n * sizeof(double))
        if b == NULL and not warm:
            return
        for e in range(self.asm.n_el):
            ng = self.sng[e]
            if ng == 0:
                continue
            nq = self.snq[e]
            idx = self.sidx + self.sptr[e]
            bb = self.Bc + self.bcptr[e]
            rows = self.srow + self.sgptr[e]
            for r in range(ng):
                row = rows[r]
                z = self.lam[row] if warm else 0.0
                if b != NULL:
                    z -= self.alpha[row] * b[row]
                zl[r] = z
            for a in range(nq):
                acc = 0.0
                for r in range(ng):
                    acc += bb[r * nq + a] * zl[r]
                y[idx[a]] -= acc

    cdef int correction(self, double *rz_stop) noexcept nogil:
        """(dx, dlam) of M dx + B^T dlam = r1, B dx = r2: conjugate gradients on the
        multipliers' Schur system S mu = B x0 - r2, S = B A^{-1} B^T, preconditioned by
        diag(alpha), from x0 = A^{-1} (r1 + B^T alpha r2); dx = x0 - A^{-1} B^T mu and
        dlam = mu + alpha (B dx - r2) satisfy the first equation exactly whatever the
        iteration count. The iterations stop when res^T alpha res is at most
        rz_stop (set to CG_TOL^2 times its first value when not positive), or after
        CG_MAX. Returns the number of solves with A; cg_steps holds
        the iterations taken (0: the residual started below rz_stop)."""
        cdef int i, k = 0, n = self.n, m = self.m
        cdef double rz, rz_new, psp, pap, step
        self.beyond_hit = False
        memcpy(self.dx, self.r1, <size_t>n * sizeof(double))
        self.mult_bt(self.r2, self.alpha, self.dx)
        self.solve_a(self.dx)
        self.mult_b(self.dx, self.res)
        rz = 0.0
        for i in range(m):
            self.res[i] -= self.r2[i]
            self.mu[i] = 0.0
            self.p[i] = self.alpha[i] * self.res[i]
            rz += self.res[i] * self.p[i]
        if not rz_stop[0] > 0.0:
            rz_stop[0] = CG_TOL * CG_TOL * rz
        self.cg_steps = 0
        while self.cg_steps < self.cg_max and rz > rz_stop[0]:
            memset(self.u, 0, <size_t>n * sizeof(double))
            self.mult_bt(self.p, NULL, self.u)
            self.solve_a(self.u)
            self.mult_b(self.u, self.sp)
            self.cg_steps += 1
            psp = 0.0
            for i in range(m):
                psp += self.p[i] * self.sp[i]
            if not psp > 0.0:
                break
            if self.beyond_quotient > 0.0:
                pap = 0.0
                for i in range(m):
                    if self.alpha[i] > 0.0:
                        pap += self.p[i] * self.p[i] / self.alpha[i]
                if psp < self.beyond_quotient * pap:
                    self.cg_steps -= 1          # not taken: beyond the rank
                    self.n_beyond_rank += 1
                    self.beyond_hit = True
                    break
            step = rz / psp
            for i in range(n):
                self.dx[i] -= step * self.u[i]
            rz_new = 0.0
            for i in range(m):
                self.mu[i] += step * self.p[i]
                self.res[i] -= step * self.sp[i]
                rz_new += self.res[i] * self.alpha[i] * self.res[i]
            for i in range(m):
                self.p[i] = self.alpha[i] * self.res[i] + (rz_new / rz) * self.p[i]
            rz = rz_new
        for i in range(m):                  # res = B dx - r2
            self.bdx[i] = self.mu[i] + self.alpha[i] * self.res[i]
        return self.cg_steps + 1

    cdef bint kkt_solve(self, const double *Q, const double *w, const double *b,
                        double *x, bint warm, bint newton) noexcept nogil:
        """x of M x + B^T lambda = Q + M w, B x = b (Q, w, b may be NULL: zero):
        iterative refinement with the true residuals r1 = Q + M w - M x - B^T lambda,
        r2 = b - B x (:meth:`refine`). warm (the accelerations): lambda starts from
        the last converged acceleration solve's multipliers (module constants, "Warm
        start"), else from zero; a warm start that meets a slow step starts again
        from zero. newton: a Newton step's solve, whose augmented-Lagrangian steps
        stop at NEWTON_STOP. Returns whether the refinement converged."""
        cdef int i, status, solves = 0, n = self.n, m = self.m
        if Q != NULL:
            memcpy(self.base, Q, <size_t>n * sizeof(double))
        else:
            memset(self.base, 0, <size_t>n * sizeof(double))
        if w != NULL:                       # M w whole: w may move pinned coordinates
            self.mult_m_full(w, self.base, True)
        for i in range(self.n_pinned):      # pinned coordinates: x stays 0 there
            self.base[self.pinned[i]] = 0.0
        self.n_solves += 1
        status = -1
        if warm and self.warm_valid:
            memcpy(self.lam, self.lam_warm, <size_t>m * sizeof(double))
            status = self.refine(b, x, True, &solves, AL_STOP)
        if status < 0:
            memset(self.lam, 0, <size_t>m * sizeof(double))
            status = self.refine(b, x, False, &solves,
                                 NEWTON_STOP if newton else AL_STOP)
        if warm:
            self.warm_valid = status == 1
            if status == 1:
                memcpy(self.lam_warm, self.lam, <size_t>m * sizeof(double))
        if status != 1:
            self.n_unconverged += 1
        self.n_iterations += solves
        if solves > self.most_iterations:
            self.most_iterations = solves
        return status == 1

    cdef int refine(self, const double *b, double *x, bint warm,
                    int *solves, double stop) noexcept nogil:
        """The refinement of kkt_solve from x = 0 and the multipliers in lam (zero unless
        warm), the solves with A added to solves[0]; the augmented-Lagrangian steps stop
        when the estimated remaining change is at most stop |x|. Each correction is one
        augmented-Lagrangian step (module docstring), its right-hand side and the
        previous step's multiplier update formed in one pass (:meth:`residual_pass`),
        while those converge fast; once a step shrinks the change by less than SLOW (a
        nearly singular B: near a singular position), the corrections are
        conjugate-gradient solves (:meth:`correction`). Returns 1 when it converged, 0
        when not, -1 when a warm start met that slow step (not continued: the
        conjugate-gradient bounds are set from a cold start's first residual)."""
        cdef int i, it, n = self.n, m = self.m, cg = 0
        cdef double nd, nx, prev = 0.0, rate, rz_stop = -1.0
        cdef bint pending = False
        memset(x, 0, <size_t>n * sizeof(double))
        for it in range(self.al_max + self.refine_max):
            if cg:
                self.residual_pass(x, b, pending, False, self.r1, self.r2)
                pending = False
                solves[0] += self.correction(&rz_stop)
                if self.beyond_hit:             # redone densely (_sparse.pyx)
                    return 0
                for i in range(m):
                    self.lam[i] += self.bdx[i]
                nd = 0.0
                nx = 0.0
                for i in range(n):
                    x[i] += self.dx[i]
                    if fabs(self.dx[i]) > nd:
                        nd = fabs(self.dx[i])
                    if fabs(x[i]) > nx:
                        nx = fabs(x[i])
            else:
                if it == 0:
                    self.first_pass(b, warm, self.dx)
                else:
                    self.residual_pass(x, b, pending, True, self.dx, NULL)
                    if it == 1:
                        rz_stop = CG_TOL * CG_TOL * self.rho
                self.solve_a_add(self.dx, x, &nd, &nx)
                pending = True
                solves[0] += 1
            if not nd > 0.0:                    # zero, or NaN (the caller checks x)
                return 1
            if cg:
                if nd <= REFINE_STOP * nx or (cg > 1 and self.cg_steps == 0):
                    return 1
                cg += 1
                if cg > self.refine_max:
                    return 0
            elif it > 0:
                rate = nd / prev
                if rate < 0.5 and nd * rate / (1.0 - rate) <= stop * nx:
                    return 1
                if rate > SLOW:
                    cg = 1
            if not cg and it + 1 >= self.al_max:
                cg = 1
            if cg and warm:
                return -1
            prev = nd
        return 0

    def reset_warm_start(self):
        """Start the next acceleration solve's multipliers from zero (every run and
        every direct call does: a result does not depend on what was solved before)."""
        self.warm_valid = False

    def solve_at(self, q, Q, b):
        """x of M x + B^T lambda = Q, B x = b with M, B assembled and A factored at q
        (the engine's constrained solve, for tests and diagnosis)."""
        cdef double[::1] qv = np.ascontiguousarray(q, dtype=float)
        cdef double[::1] Qv = np.ascontiguousarray(Q, dtype=float)
        cdef double[::1] bv = np.ascontiguousarray(b, dtype=float)
        x = np.zeros(self.n)
        cdef double[::1] xv = x
        if qv.shape[0] != self.n or Qv.shape[0] != self.n or bv.shape[0] != self.m:
            raise ValueError("q, Q or b does not match the model's sizes")
        self.assemble_mb(&qv[0], ASM_M | ASM_B)
        if self.factor(&qv[0]) < 0:
            raise ArithmeticError("the factorisation of M + B^T alpha B failed")
        self.solve_constrained(&Qv[0], NULL, &bv[0], &xv[0])
        return x

    def solve_a_at(self, q, y):
        """A^{-1} y with A = M + B^T diag(alpha) B factored at q, and alpha."""
        cdef double[::1] qv = np.ascontiguousarray(q, dtype=float)
        x = np.array(y, dtype=float)
        cdef double[::1] xv = x
        self.assemble_mb(&qv[0], ASM_M | ASM_B)
        if self.factor(&qv[0]) < 0:
            raise ArithmeticError("the factorisation of M + B^T alpha B failed")
        self.solve_a(&xv[0])
        return x, np.array(<double[:self.m]>self.alpha)
