# The power of the non-conservative forces at a stage state, for the energy check
# with the work added back (see _power.pyx).
from libc.string cimport memcpy

from ._assemble cimport ASM_F
from ._engine cimport Engine
from ._sparse_blocks cimport SparseBlocks


cdef struct Power:
    int on                    # 0: nothing to track (a conservative model)
    int n_params              # the element parameters: their count,
    double *nc                # ... a copy with the conservative ones zeroed (work),
    int n_zero                # ... and which are zeroed
    int *zero
    int constraints           # add the constraint forces' power (driven models),
    int sparse                # ... M from the sparse path's element blocks,
    double *ma                # ... M a (n numbers of work)


cdef inline double stage_power(Engine e, Power *w, const double *q, const double *v,
                               const double *a) noexcept nogil:
    """P = v . f_nc(q, v, t) [+ v . (M a + h - f) = -v . B^T lambda]: the power of the
    applied forces that have no potential (f assembled with the conservative
    parameters zeroed: gravity, constant forces, spring stiffnesses) and, for driven
    models, of the constraint forces, at the stage (q, v) whose accelerations a the
    engine has just solved (M, h, f still assembled there; on the sparse path M as its
    element blocks)."""
    cdef int i, j, n = e.n
    cdef double p = 0.0, acc
    cdef double *saved
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
    saved = e.asm.params
    memcpy(w.nc, saved, w.n_params * sizeof(double))
    for i in range(w.n_zero):
        w.nc[w.zero[i]] = 0.0
    e.asm.params = w.nc
    e.asm.assemble(q, v, ASM_F)
    e.asm.params = saved
    for i in range(n):
        p += v[i] * e.asm.f[i]
    return p


cdef Power *power_state(object tracker) except? NULL
