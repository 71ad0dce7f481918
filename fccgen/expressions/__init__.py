"""The expression language of the model file: the checked grammar of expressions in t,
the coordinates, joint angles and parameters (``grammar``), the tables they may call
(``tables``), and the time derivatives of time functions (``time_jets``)."""
