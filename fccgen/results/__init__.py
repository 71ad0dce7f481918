"""The results of a run and where they go: the :class:`Result` table (``result``), its
files (``files``), the provenance written with them (``provenance``) and the printed
summary (``summary``)."""
from .result import InitialState, Result, check_output, partial_path, timed_run

__all__ = ["InitialState", "Result", "check_output", "partial_path", "timed_run"]
