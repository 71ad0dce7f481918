"""Events (docs/design.md §2b): event functions s(q, v, t) and switchable joint rows
derived with SymPy (symbolic.py), printed to C and compiled into one small module per
model (build.py), located and acted on by the compiled runtime
(fccgen/runtime/_events.pyx); the event table of a run (table.py)."""
