"""What ``fccgen check`` says about a model without running it (``check``): the
coordinates, the degrees of freedom, the redundant equations and the generated
classes."""
