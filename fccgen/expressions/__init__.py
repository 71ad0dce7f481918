"""The expression language of the model file: the checked grammar of expressions in t,
the coordinates, joint angles and parameters (``grammar``), the tables of time they may
call (``tables``), the model's named tables that loads call (``named_tables``), and the
time derivatives of time functions (``time_jets``)."""
