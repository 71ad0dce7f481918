"""What every run shares, compiled or NumPy: the divergence and drift guards
(``guards``), the energy check with work added back (``energy_check``), the SciPy
methods that step in Python (``scipy_ivp``), the joint rows that events held at each
record, for the reactions and driver forces after a run (``held_rows``), and, when a
run fails, the item of the model file it comes from (``locate``), with the
explanation added to the error (``explain``, ``massless``)."""
