# The power of the forces without potential at a stage state, for the energy check
# with the work added back (see _power.pyx).
from ._assemble cimport ASM_F, Assembler
from ._engine cimport Engine
from ._sparse_blocks cimport SparseBlocks


cdef struct Power:
    int on                    # 0: nothing to track (a conservative model)
    void *nc                  # the Assembler of the elements with forces without
                              # potential (owned by the WorkTracker)
    int n_params              # its parameters: how many,
    int *src                  # ... each one's index among the engine's parameters,
    int n_zero                # ... and which are zeroed (spring stiffnesses)
    int *zero
    int constraints           # add the constraint forces' power (driven models),
    int sparse                # ... M from the sparse path's element blocks,
    double *ma                # ... M a (n numbers of work)


cdef inline double stage_power(Engine e, Power *w, const double *q, const double *v,
                               const double *a) noexcept nogil:
    """P = v . f_nc(q, v, t) [+ v . (M a + h - f) = -v . B^T lambda]: the power of the
    applied forces that have no potential (the elements that have some, assembled
    with their stiffnesses zeroed and the engine's present parameters: time,
    references) and, for driven models, of the constraint forces, at the stage
    (q, v) whose accelerations a the engine has just solved (M, h, f still assembled
    there; on the sparse path M as its element blocks)."""
    cdef int i, j, n = e.n
    cdef double p = 0.0, acc
    if not w.on:
        return 0.0
    if w.constraints:
        if w.sparse:
            (<SparseBlocks>e).mult_m_full(a, w.ma, False)
        else:
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc = acc + e.asm.M[i * n + j] * a[j]
                w.ma[i] = acc
        for i in range(n):
            p += v[i] * (w.ma[i] + e.asm.h[i] - e.asm.f[i])
    for i in range(w.n_params):
        (<Assembler>w.nc).params[i] = e.asm.params[w.src[i]]
    for i in range(w.n_zero):
        (<Assembler>w.nc).params[w.zero[i]] = 0.0
    (<Assembler>w.nc).assemble(q, v, ASM_F)
    for i in range(n):
        p += v[i] * (<Assembler>w.nc).f[i]
    return p


cdef Power *power_state(object tracker) except? NULL
