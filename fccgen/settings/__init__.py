"""The settings of a run: the methods and their options (``methods``), the solver and
run settings a model file or a call may give (``run``), and the limits of methods on
some models (``limits``)."""
