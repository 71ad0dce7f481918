# cython: language_level=3
"""The Python face of the C engine's sparse path: accelerations and projections in time
linear in the model's size (engine/fcc_sparse_*.c, fcc_al_refine.c: the element blocks,
the LDL^T of A = M + B^T diag(alpha) B, the augmented-Lagrangian refinement, chord
steps, the dense fallback and the rank-growth watch; their docstrings say how and why).

SparseEngine is an Engine whose C struct takes the sparse path. The set-up analysis
(which coordinates are pinned, which entries the planar pattern leaves out: 
sparse_setup.py; the fill-reducing order and scatter maps: sparsity.py) runs here once,
its results handed to the C pattern (fcc_pattern); so does the start of the rank watch
(an SVD of B), and its restart after a rank increase, called back from C.
"""
from types import SimpleNamespace

import numpy as np

from fccgen import rank as rank_rule

from . import sparse_setup
from .setup_reuse import jacobian_key, shared_decision
from .sparsity import jacobian_csr

from ._assemble cimport ASM_B, ASM_G, ASM_M, Assembler
from ._cengine cimport (FCC_AL_MAX, FCC_CG_MAX, FCC_ERR_ARGUMENT, FCC_OK, FCC_REFINE_MAX,
                        FCC_TRACK_MAX, fcc_engine, fcc_model, fcc_pattern,
                        fcc_pattern_free, fcc_pattern_init, fcc_pattern_set_guards,
                        fcc_pattern_set_structure, fcc_pattern_set_view,
                        fcc_pattern_set_switchable,
                        fcc_solve_constrained, fcc_sp_assemble_mb, fcc_sp_factor,
                        fcc_sp_solve_a, fcc_sparse_free, fcc_sparse_init,
                        fcc_sparse_resize, fcc_sparse_set_beyond_rank,
                        fcc_sparse_set_watch)
from ._engine cimport Engine

TRACK_MAX = FCC_TRACK_MAX
# sigma_{r+1} > GROW_TOL sigma_1 raises the rank (fccgen.rank.GROW_TOL, the dense rule).
GROW_TOL = rank_rule.GROW_TOL


cdef void _restart_watch(void *ctx, fcc_engine *e) noexcept nogil:
    """The C engine's call after a rank increase: the watch from the null space of B
    there (rare: once per change of the rank)."""
    with gil:
        (<SparseEngine>ctx)._restart()


def _ints(values):
    return np.ascontiguousarray(values, dtype=np.intc)


def _doubles(values):
    return np.ascontiguousarray(values, dtype=float)


cdef const int *_ip(int[::1] x):
    return &x[0] if x.shape[0] else NULL


cdef const double *_dp(double[::1] x):
    return &x[0] if x.shape[0] else NULL


cdef object ints(const int *p, int k):
    """p[:k] as a fresh array."""
    return np.array([p[i] for i in range(k)], dtype=np.intc)


cdef object doubles(const double *p, int k):
    """p[:k] as a fresh array."""
    return np.array([p[i] for i in range(k)], dtype=float)


def _watch_basis(B, groups, int rank):
    """The right singular vectors of the row-scaled dense B beyond the first rank."""
    m, n = B.shape
    _, _, vt = np.linalg.svd(B / rank_rule.row_scales(B, groups)[:, None],
                             full_matrices=m < n)     # vt: n x n
    return vt[rank:].T


cdef class SparseEngine(Engine):
    """An Engine whose solves use the sparse augmented-Lagrangian refinement. Call
    :meth:`set_structure` (fccgen.runtime.sparsity) before use."""
    cdef fcc_pattern pat
    cdef bint pat_live
    cdef object start_key             # (rank, q bytes) of the basis in start_basis
    cdef object start_basis           # the watch's basis from the SVD at that start
    cdef int start_n_track

    def __cinit__(self, Assembler asm, *args, **kwargs):
        if fcc_pattern_init(&self.pat, &asm.model) != FCC_OK:
            raise MemoryError("cannot allocate the sparse solve's pattern")
        self.pat_live = True
        if fcc_sparse_init(&self.c, &self.pat) != FCC_OK:
            raise MemoryError("cannot allocate the sparse solve's work arrays")
        self.c.sp.restart_watch = _restart_watch
        self.c.sp.restart_ctx = <void *>self

    def __dealloc__(self):
        if self.live:
            fcc_sparse_free(&self.c)          # Engine.__dealloc__ frees the rest
        if self.pat_live:
            fcc_pattern_free(&self.pat)

    # -- set-up --------------------------------------------------------------------
    def _elements(self):
        """The elements as sparse_setup reads them (its docstring)."""
        cdef int e, n_el = self.asm.n_el
        cdef const fcc_model *md = &self.asm.model
        return SimpleNamespace(
            nq=np.array([md.cls[e].n_q for e in range(n_el)], dtype=np.intp),
            ng=np.array([md.cls[e].n_g for e in range(n_el)], dtype=np.intp),
            has_m=np.array([md.cls[e].mass_matrix != NULL for e in range(n_el)], bool),
            has_b=np.array([md.cls[e].constraint_jacobian != NULL
                            for e in range(n_el)], bool),
            has_rate=np.array([md.cls[e].constraint_rate != NULL
                               for e in range(n_el)], bool),
            qptr=np.array([md.qptr[e] for e in range(n_el + 1)], dtype=np.intp),
            qidx=np.array([md.qidx[e] for e in range(md.qptr[n_el])], dtype=np.intp),
            gptr=np.array([md.gptr[e] for e in range(n_el + 1)], dtype=np.intp),
            mptr=np.array([self.pat.mptr[e] for e in range(n_el + 1)], dtype=np.intp),
            bptr=np.array([self.pat.bptr[e] for e in range(n_el + 1)], dtype=np.intp))

    def _blocks(self, q, int flags):
        """(Mblk, Bblk) copies: the element blocks assembled at q (flags ASM_M,
        ASM_B)."""
        cdef double[::1] qv = self.vector(q, "q")
        cdef int n_el = self.asm.n_el
        fcc_sp_assemble_mb(&self.c, &qv[0], flags)
        nm, nb = self.pat.mptr[n_el], self.pat.bptr[n_el]
        return (np.array(<double[:nm]>self.c.sp.Mblk) if nm else np.zeros(0),
                np.array(<double[:nb]>self.c.sp.Bblk) if nb else np.zeros(0))

    def _check_samples(self, samples):
        qs = np.ascontiguousarray(np.atleast_2d(samples), dtype=float)
        if qs.shape[1] != self.c.n:
            raise ValueError(f"samples have {qs.shape[1]} coordinates, the model "
                             f"{self.c.n}")
        return qs

    def set_pinned(self, samples):
        """Leave out of the solve the coordinates that linear constraints with constant
        rows hold still, and those rows (before planar_pattern and set_structure):
        sparse_setup.pinned_view says which. The same answer as the full solve, while
        the fixed rows keep their entries and hold (checked at every assembly and
        position projection): otherwise the pattern trips and the solver redoes the
        call on the full pattern, as for planar_pattern. Returns the number of pinned
        coordinates (0: the full view is kept)."""
        if self.pat.ready or self.pat.compact:
            raise RuntimeError("the structure is already set")
        qs = self._check_samples(samples)
        if self.pat.bptr[self.asm.n_el] == 0:
            return 0
        blocks = [self._blocks(q, ASM_B)[1] for q in qs]
        g0 = self.asm.quantity(ASM_G, qs[0])
        view = sparse_setup.pinned_view(self._elements(), blocks, g0,
                                        self.c.set.position_tol)
        if view is None:
            return 0
        cdef int[::1] snq = _ints(view["snq"]), sloc = _ints(view["sloc"])
        cdef int[::1] sng = _ints(view["sng"]), srloc = _ints(view["srloc"])
        cdef int[::1] pinned = _ints(view["pinned"]), rows = _ints(view["fixed_rows"])
        cdef int[::1] off = _ints(view["fixed_off"])
        cdef double[::1] efix = _doubles(view["efix"]), norm = _doubles(view["fixed_norm"])
        cdef double[::1] gtol = _doubles(view["fixed_g_tol"])
        cdef double[::1] val = _doubles(view["fixed_val"]), tol = _doubles(view["fixed_tol"])
        if (fcc_pattern_set_view(&self.pat, _ip(snq), _ip(sloc), _ip(sng), _ip(srloc),
                                 _dp(efix), pinned.shape[0], _ip(pinned), rows.shape[0],
                                 _ip(rows), _dp(norm), _dp(gtol), off.shape[0], _ip(off),
                                 _dp(val), _dp(tol)) != FCC_OK
                or fcc_sparse_resize(&self.c) != FCC_OK):
            raise MemoryError("cannot allocate the sparse solve's view")
        return self.pat.n_pinned

    def planar_pattern(self, samples):
        """Take the pattern of A from the element blocks at the coordinate vectors in
        samples (before set_structure; sparse_setup.planar_masks): a model written in
        a plane keeps its out-of-plane entries exactly zero while it moves in it, so
        the fill of L is about halved there. Every later assembly checks the entries
        left out: a nonzero one trips the pattern (the factorisation then fails with
        ERR_PATTERN and the solver redoes the call on the full pattern,
        paths.make_engine). Returns (mask_ptr, mask) for
        fccgen.runtime.sparsity.structure."""
        if self.pat.ready:
            raise RuntimeError("the structure is already set")
        qs = self._check_samples(samples)
        samples_blocks = [self._blocks(q, ASM_M | ASM_B) for q in qs]
        view = self.view_entries() if self.pat.compact else None
        ptr, mask, offs_m, tol_m, offs_b, tol_b = sparse_setup.planar_masks(
            self._elements(), samples_blocks, view)
        cdef int[::1] zm = _ints(offs_m), zb = _ints(offs_b)
        cdef double[::1] tm = _doubles(tol_m), tb = _doubles(tol_b)
        if fcc_pattern_set_guards(&self.pat, zm.shape[0], _ip(zm), _dp(tm), zb.shape[0],
                                  _ip(zb), _dp(tb)) != FCC_OK:
            raise MemoryError("cannot allocate the sparse solve's guards")
        self.c.sp.tripped = False
        if not self.pat.compact:
            return ptr, mask
        return sparse_setup.view_masks((ptr, mask), self.solve_locals(),
                                       self.solve_elements()[2])

    def set_structure(self, perm, Ap, Ai, emap_ptr, emap):
        """Take the pattern of A and the scatter maps (fccgen.runtime.sparsity.Structure)
        and do the symbolic factorisation."""
        if self.pat.ready:
            raise RuntimeError("the structure is already set")
        cdef int n = self.c.n, e
        cdef int[::1] pv = _ints(perm), apv = _ints(Ap), aiv = _ints(Ai)
        epv = _ints(emap_ptr)
        if pv.shape[0] != n or apv.shape[0] != n + 1 or epv.shape[0] != self.asm.n_el + 1:
            raise ValueError("the structure does not match the engine's sizes")
        if sorted(np.asarray(pv).tolist()) != list(range(n)):
            raise ValueError("perm is not a permutation")
        snq = [self.pat.snq[e] for e in range(self.asm.n_el)]
        cdef int[::1] ptr, ea, eb, pos
        ptr, ea, eb, pos = sparse_setup.structure_entries(epv, emap, snq, apv[n])
        rc = fcc_pattern_set_structure(&self.pat, &pv[0], &apv[0], _ip(aiv), &ptr[0],
                                       _ip(ea), _ip(eb), _ip(pos))
        if rc == FCC_ERR_ARGUMENT:
            raise ValueError("the pattern of A lacks a pinned coordinate's diagonal")
        if rc != FCC_OK or fcc_sparse_resize(&self.c) != FCC_OK:
            raise MemoryError("cannot allocate the sparse solve's factorisation")

    def set_switchable(self, sw_ptr, sw_idx, emap_ptr, emap):
        """Take the switchable rows folded into A (after set_structure, whose pattern
        holds their pairs; engine/fcc_sparse_fold.c): per row the free coordinates it
        reads (sw_ptr, sw_idx) and its scatter map (emap_ptr, emap: per local pair, the
        value's index in A or -1)."""
        if not self.pat.ready:
            raise RuntimeError("set the structure first")
        cdef int[::1] ptr = _ints(sw_ptr), idx = _ints(sw_idx)
        cdef int n_sw = ptr.shape[0] - 1
        sizes = np.diff(np.asarray(ptr))
        cdef int[::1] ep, ea, eb, pos
        ep, ea, eb, pos = sparse_setup.structure_entries(_ints(emap_ptr), emap, sizes,
                                                         self.pat.nnz_a)
        rc = fcc_pattern_set_switchable(&self.pat, n_sw, &ptr[0], _ip(idx), &ep[0],
                                        _ip(ea), _ip(eb), _ip(pos))
        if rc == FCC_ERR_ARGUMENT:
            raise ValueError("the switchable rows do not match the pattern of A")
        if rc != FCC_OK or fcc_sparse_resize(&self.c) != FCC_OK:
            raise MemoryError("cannot allocate the switchable rows")

    @property
    def switchable_rows(self):
        """How many switchable rows the pattern of A holds (0: none folded)."""
        return self.pat.n_sw

    def solve_elements(self):
        """(q_ptr, q_idx, couples) of the solve's view (set_pinned): each element's
        free coordinates, and whether it adds a block to A (a mass matrix or kept
        rows on them); the assembler's elements when nothing is pinned."""
        cdef int e, n_el = self.asm.n_el
        q_ptr = np.array([self.pat.sptr[e] for e in range(n_el + 1)], dtype=np.intc)
        q_idx = np.array([self.pat.sidx[e] for e in range(self.pat.sptr[n_el])],
                         dtype=np.intc)
        couples = np.array([self.pat.snq[e] > 0 and (
            self.pat.mcptr[e + 1] > self.pat.mcptr[e] or self.pat.sng[e] > 0)
            for e in range(n_el)], dtype=bool)
        return q_ptr, q_idx, couples

    def view_entries(self):
        """(in_m, in_b): for each entry of the mass and Jacobian blocks, whether the
        solve's view (set_pinned) reads it (its coordinates free, its row kept)."""
        pinned, fixed = self.pinned_coordinates
        return sparse_setup.view_entries(self._elements(), pinned, fixed, self.c.n,
                                         self.c.m)

    def solve_locals(self):
        """(sizes, s_ptr, s_loc): each element's number of local coordinates, and
        where each free one of the solve's view (set_pinned) sits in that list."""
        cdef int e, n_el = self.asm.n_el
        return (np.array([self.asm.model.cls[e].n_q for e in range(n_el)], dtype=np.intp),
                np.array([self.pat.sptr[e] for e in range(n_el + 1)], dtype=np.intp),
                np.array([self.pat.sloc[e] for e in range(self.pat.sptr[n_el])],
                         dtype=np.intp))

    @property
    def pinned_coordinates(self):
        """The coordinates the solve leaves out (set_pinned), and the fixed rows."""
        cdef int i
        return (np.array([self.pat.pinned[i] for i in range(self.pat.n_pinned)],
                         dtype=np.intp),
                np.array([self.pat.fixed_rows[i] for i in range(self.pat.n_fixed_rows)],
                         dtype=np.intp))

    def pattern_arrays(self):
        """The pattern's constants as the set-up gave them: {"view": the arguments of
        fcc_pattern_set_view (None without pinned coordinates), "guards": those of
        fcc_pattern_set_guards, "structure": those of fcc_pattern_set_structure (None
        before set_structure), "switchable": those of fcc_pattern_set_switchable (None
        without switchable rows)}, each a dict of fresh arrays; what another instance of
        the engine (a program that holds the C engine alone) is built from."""
        cdef int n_el = self.asm.n_el
        cdef const fcc_pattern *P = &self.pat
        view = None
        if P.compact:
            view = dict(snq=ints(P.snq, n_el), sloc=ints(P.sloc, P.sptr[n_el]),
                        sng=ints(P.sng, n_el), srloc=ints(P.srloc, P.sgptr[n_el]),
                        efix=doubles(P.efix, n_el), pinned=ints(P.pinned, P.n_pinned),
                        fixed_rows=ints(P.fixed_rows, P.n_fixed_rows),
                        fixed_norm=doubles(P.fixed_norm, P.n_fixed_rows),
                        fixed_g_tol=doubles(P.fixed_g_tol, P.n_fixed_rows),
                        fixed_off=ints(P.fixed_off, P.n_fixed),
                        fixed_val=doubles(P.fixed_val, P.n_fixed),
                        fixed_tol=doubles(P.fixed_tol, P.n_fixed))
        guards = dict(zero_m=ints(P.zero_m, P.n_zero_m),
                      zero_m_tol=doubles(P.zero_m_tol, P.n_zero_m),
                      zero_b=ints(P.zero_b, P.n_zero_b),
                      zero_b_tol=doubles(P.zero_b_tol, P.n_zero_b))
        structure = None
        if P.ready:
            structure = dict(perm=ints(P.perm, P.n), Ap=ints(P.Ap, P.n + 1),
                             Ai=ints(P.Ai, P.nnz_a), ent_ptr=ints(P.ent_ptr, n_el + 1),
                             ent_a=ints(P.ent_a, P.ent_ptr[n_el]),
                             ent_b=ints(P.ent_b, P.ent_ptr[n_el]),
                             ent_pos=ints(P.ent_pos, P.ent_ptr[n_el]))
        switchable = None
        if P.n_sw > 0:
            switchable = dict(sw_ptr=ints(P.sw_ptr, P.n_sw + 1),
                              sw_idx=ints(P.sw_idx, P.sw_ptr[P.n_sw]),
                              sw_ent_ptr=ints(P.sw_ent_ptr, P.n_sw + 1),
                              sw_ent_a=ints(P.sw_ent_a, P.sw_ent_ptr[P.n_sw]),
                              sw_ent_b=ints(P.sw_ent_b, P.sw_ent_ptr[P.n_sw]),
                              sw_ent_pos=ints(P.sw_ent_pos, P.sw_ent_ptr[P.n_sw]))
        return dict(view=view, guards=guards, structure=structure,
                    switchable=switchable)

    @property
    def pattern_tripped(self):
        """Whether an assembly found a block entry nonzero that was zero where the
        pattern was taken (planar_pattern), or a fixed row moved."""
        return bool(self.c.sp.tripped)

    @property
    def nonzeros(self):
        """(nonzeros of upper(A), nonzeros of the strict lower part of L)."""
        return self.pat.nnz_a, self.pat.nnz_l

    @property
    def factored_columns(self):
        """The columns the LDL^T and its solves cover (set_structure: all but the
        trailing pinned ones)."""
        return self.pat.n_lead

    # -- the refinement's settings and statistics -------------------------------------
    def limit_refinement(self, int corrections=FCC_REFINE_MAX, int cg_steps=FCC_CG_MAX,
                         int al_steps=FCC_AL_MAX):
        """Cap the corrections, conjugate-gradient steps and augmented-Lagrangian
        steps of a solve (defaults: the engine's FCC_REFINE_MAX, FCC_CG_MAX,
        FCC_AL_MAX); low caps make solves stop unconverged, for tests of what
        follows."""
        if corrections < 1 or cg_steps < 0 or al_steps < 1:
            raise ValueError("at least one correction and one augmented-Lagrangian "
                             "step, and no negative step count")
        self.c.sp.refine_max = corrections
        self.c.sp.cg_max = cg_steps
        self.c.sp.al_max = al_steps

    def set_beyond_rank(self, double kept_sigma):
        """Stop the conjugate-gradient corrections at directions beyond the decided
        rank (engine/fcc_al_refine.c, "Directions beyond the decided rank"):
        kept_sigma is the smallest scaled singular value the rank decision kept
        (sigma_r / sigma_1); 0 turns the stop off (rows dependent exactly, or none)."""
        fcc_sparse_set_beyond_rank(&self.c, kept_sigma)

    @property
    def beyond_rank_quotient(self):
        """The Rayleigh quotient below which the corrections stop (0: off)."""
        return self.c.sp.beyond_quotient

    def solve_statistics(self):
        """Factorisations and solves since the last rank decision, refinement iterations
        in all and at most in one solve, solves that did not converge, and the
        factorisations redone with a raised penalty near a singular position
        (fcc_al_refine.c)."""
        return dict(factorisations=self.c.sp.n_factor, solves=self.c.sp.n_solves,
                    boosted_factorisations=self.c.sp.n_boosted,
                    iterations=self.c.sp.n_iterations,
                    max_iterations=self.c.sp.most_iterations,
                    unconverged=self.c.sp.n_unconverged,
                    beyond_rank_stops=self.c.sp.n_beyond_rank)

    def reset_warm_start(self):
        """Start the next acceleration solve's multipliers from zero (every run and
        every direct call does: a result does not depend on what was solved before)."""
        self.c.sp.warm_valid = False

    def set_dense_fallback_max(self, int n_max):
        """Redo unconverged solves densely only for models of at most n_max
        coordinates (default FCC_DENSE_FALLBACK_MAX; 0: never), for tests."""
        self.c.sp.dense_fallback_max = n_max

    @property
    def dense_fallback_max(self):
        return self.c.sp.dense_fallback_max

    def _factored_at(self, q):
        cdef double[::1] qv = self.vector(q, "q", False)
        fcc_sp_assemble_mb(&self.c, &qv[0], ASM_M | ASM_B)
        if fcc_sp_factor(&self.c, &qv[0]) < 0:
            raise ArithmeticError("the factorisation of M + B^T alpha B failed")

    def solve_at(self, q, Q, b):
        """x of M x + B^T lambda = Q, B x = b with M, B assembled and A factored at q
        (the engine's constrained solve, for tests and diagnosis)."""
        cdef double[::1] Qv = _doubles(Q), bv = _doubles(b)
        x = np.zeros(self.c.n)
        cdef double[::1] xv = x
        if len(q) != self.c.n or Qv.shape[0] != self.c.n or bv.shape[0] != self.c.m:
            raise ValueError("q, Q or b does not match the model's sizes")
        self._factored_at(q)
        fcc_solve_constrained(&self.c, &Qv[0], NULL, _dp(bv), &xv[0])
        return x

    def solve_a_at(self, q, y):
        """A^{-1} y with A = M + B^T diag(alpha) B factored at q, and alpha."""
        x = np.array(y, dtype=float)
        cdef double[::1] xv = x
        self._factored_at(q)
        fcc_sp_solve_a(&self.c, &xv[0])
        return x, np.array(<double[:self.c.m]>self.c.sp.alpha)

    # -- the rank decision and its watch ------------------------------------------------
    def decide_rank(self, q, rank):
        """Keep the decision for the reports (the solve itself needs no rank), start
        the statistics anew, and start the rank-growth watch (engine/fcc_sparse_watch.c)
        from the null space of the row-scaled B at q when the rank can grow (rank below
        min(n, m)) and n - rank <= TRACK_MAX; deciding again at the same q and rank
        (a run from its initial state) reuses that start's basis instead of a new SVD."""
        cdef double[::1] saved
        cdef int n = self.c.n
        Engine.decide_rank(self, q, rank)
        if q is None:
            return
        key = (rank, np.asarray(q, dtype=float).tobytes())
        if key != self.start_key:           # a run decides again at its initial state
            self.start_key = None
            self.start_watch(self.asm.quantity(ASM_B, q)
                             if n <= rank_rule.dense_columns_max() else
                             jacobian_csr(self.asm, q), rank)
            self.start_basis = np.array(<double[:n * TRACK_MAX]>self.c.sp.track)
            self.start_n_track = self.c.sp.n_track
            self.start_key = key
        else:
            saved = self.start_basis
            fcc_sparse_set_watch(&self.c, self.start_n_track, &saved[0], GROW_TOL)

    def start_watch(self, B, int rank):
        """N = the right singular vectors of the row-scaled B beyond the first rank
        (its null space when rank is B's), when the rank can grow (rank below
        min(n, m)) and n - rank <= TRACK_MAX; otherwise no watch. B dense: a full SVD;
        B sparse (models above rank.dense_columns_max() coordinates, where that SVD
        would take minutes): shift-invert Lanczos on B^T B
        (fccgen.rank.sparse.smallest_right_vectors)."""
        cdef int n = self.c.n, m = self.c.m, k = n - rank, i
        fcc_sparse_set_watch(&self.c, 0, NULL, GROW_TOL)
        if rank < 0 or rank >= min(n, m) or k > TRACK_MAX:
            return
        groups = [self.asm.model.row_group[i] for i in range(m)]
        try:
            if isinstance(B, np.ndarray):
                # a function of B alone: kept per process by its bytes, as the rank
                # decisions are (setup_reuse.shared_decision), so an engine of other
                # masses at the same start (with_parameters, simulate_many) reuses it
                basis, _ = shared_decision(jacobian_key("watch", B, groups, rank),
                                           lambda: _watch_basis(B, groups, rank))
            else:
                from fccgen.rank import sparse as rank_sparse
                basis = rank_sparse.smallest_right_vectors(
                    rank_sparse.scaled(B, groups), k)
        except (np.linalg.LinAlgError, ArithmeticError, RuntimeError):
            return                           # no basis: the start's rank is kept
        cdef double[::1] cols = np.ascontiguousarray(np.asarray(basis).T, dtype=float).ravel()
        fcc_sparse_set_watch(&self.c, k, &cols[0], GROW_TOL)

    @property
    def watched_directions(self):
        """The directions the rank-growth watch tracks (0: no watch)."""
        return self.c.sp.n_track

    def _restart(self):
        """The watch from the null space of B after a rank increase (_restart_watch)."""
        cdef int n = self.c.n, m = self.c.m
        self.start_watch(np.array(<double[:m * n]>self.c.sol.A).reshape(m, n),
                         self.c.sol.rank_fixed)

    def accelerations(self, q, v):
        """Engine.accelerations, from zero multipliers (a direct call does not depend
        on what was solved before)."""
        self.reset_warm_start()
        return Engine.accelerations(self, q, v)

    def baumgarte_accelerations(self, q, v, double alpha, double beta):
        """Engine.baumgarte_accelerations, from zero multipliers."""
        self.reset_warm_start()
        return Engine.baumgarte_accelerations(self, q, v, alpha, beta)

    def rank_statistics(self):
        """As Engine.rank_statistics; drops are the dense fallback's factorisations
        with a pivot dropped within the decided rank (the dense path's meaning),
        largest_dropped the largest bound ||B_s N||_F on sigma_{r+1} / sigma_1 met by
        the rank-growth watch; sparse_solves, sparse_unconverged (refinements that
        did not converge), sparse_dense_fallbacks (of those, redone densely) and
        sparse_beyond_rank (of those, stopped at a direction beyond the decided rank);
        sparse_iterations and sparse_most_iterations, the solves with A the
        refinements took, in all and in the longest (engine/fcc_al_refine.c); chord_steps and chord_steps_undone, the position projection's chord steps kept
        and undone (engine/fcc_sparse_engine.c)."""
        stats = Engine.rank_statistics(self)
        stats.update(factorisations=self.c.sp.n_factor, drops=self.c.sol.n_drop,
                     svd_checks=self.c.sp.n_svd, smallest_kept=1.0,
                     largest_dropped=self.c.sp.bound_max,
                     sparse_solves=self.c.sp.n_solves,
                     sparse_unconverged=self.c.sp.n_unconverged,
                     sparse_dense_fallbacks=self.c.sp.n_fallback,
                     sparse_beyond_rank=self.c.sp.n_beyond_rank,
                     sparse_iterations=self.c.sp.n_iterations,
                     sparse_most_iterations=self.c.sp.most_iterations,
                     chord_steps=self.c.sp.n_chord,
                     chord_steps_undone=self.c.sp.n_chord_undone)
        return stats

    cdef dict error_record(self):
        rec = Engine.error_record(self)
        rank = self.c.sol.rank_fixed
        rec.update(rank=rank, nullity=self.c.n - rank if rank >= 0 else self.c.n,
                   sparse=True)
        return rec
