# The Python face of the C assembler (engine/fcc_assemble.h; see _assemble.pyx).
from ._cengine cimport (FCC_ASM_B, FCC_ASM_BODY, FCC_ASM_C, FCC_ASM_E, FCC_ASM_F,
                        FCC_ASM_G, FCC_ASM_H, FCC_ASM_KQ, FCC_ASM_KV, FCC_ASM_M,
                        FCC_ASM_T, fcc_assembly, fcc_model)
from ._model_table cimport fcc_element_class, fcc_model_table

# What to assemble: a bit mask (fcc_base.h).
cdef enum:
    ASM_M = FCC_ASM_M
    ASM_H = FCC_ASM_H
    ASM_F = FCC_ASM_F
    ASM_G = FCC_ASM_G
    ASM_B = FCC_ASM_B
    ASM_C = FCC_ASM_C
    ASM_E = FCC_ASM_E
    ASM_BODY = FCC_ASM_BODY
    ASM_KQ = FCC_ASM_KQ
    ASM_KV = FCC_ASM_KV
    ASM_T = FCC_ASM_T


cdef class Assembler:
    cdef readonly int n_q, n_g, n_el, n_bodies
    cdef readonly object owner           # keeps the kernels' module alive
    cdef fcc_model model                 # the constants
    cdef fcc_assembly a                  # this instance's parameters and buffers
    cdef bint live                       # model and a are initialised

    cdef double[::1] _state(self, object x, str name)
