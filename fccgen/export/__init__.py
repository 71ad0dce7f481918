"""Export of a model out of Python: a standalone C project and an FMI 2.0
co-simulation FMU (docs/export.md)."""
from .c_project import ExportError, export_c

__all__ = ["ExportError", "export_c"]
