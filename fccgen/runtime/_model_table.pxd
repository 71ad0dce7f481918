# Cython view of fccgen_model.h: the table of element-class kernels a generated module
# hands to the runtime.

cdef extern from "fccgen_model.h":
    int FCC_ABI_VERSION
    const char *FCC_CAPSULE_NAME

    ctypedef void (*fcc_kernel_q)(const double *q, const double *p,
                                  double *out) noexcept nogil
    ctypedef void (*fcc_kernel_qv)(const double *q, const double *v, const double *p,
                                   double *out) noexcept nogil

    ctypedef struct fcc_element_class:
        const char *name
        int n_q
        int n_p
        int n_g
        fcc_kernel_q mass_matrix
        fcc_kernel_qv h_vector
        fcc_kernel_qv applied_forces
        fcc_kernel_q constraints
        fcc_kernel_q constraint_jacobian
        fcc_kernel_qv constraint_bias
        fcc_kernel_qv energy
        fcc_kernel_qv body_outputs
        fcc_kernel_qv force_jacobian_q
        fcc_kernel_q force_jacobian_v
        fcc_kernel_q constraint_rate

    ctypedef struct fcc_model_table:
        int abi_version
        const char *structure_hash
        int n_classes
        const fcc_element_class *classes
