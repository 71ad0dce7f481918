"""Design sensitivities: derivatives of a run's outputs with respect to the model's
numbers (the ``with_parameters`` keys), from symbolic parameter derivatives of the
element kernels (fccgen.derive.parameters, compiled by :mod:`.build`)."""
