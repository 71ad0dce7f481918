"""The ``fccgen export`` command (fccgen/cli.py hands it over)."""
from __future__ import annotations


def run_export(args, progress) -> int:
    from .c_project import ExportError, export_c
    if not args.c_dir and not args.fmu:
        raise ExportError("say what to write: --c DIR (a C project) or --fmu FILE.fmu")
    sensitivities = getattr(args, "sensitivities", False)
    if isinstance(sensitivities, str) and args.c_dir:
        raise ExportError("--sensitivities KEY,KEY chooses the FMU's outputs; the C "
                          "project carries every key's sensitivity and its program "
                          "chooses them at run time: give --c DIR with --sensitivities "
                          "alone (docs/export.md, \"Sensitivities\")")
    location = getattr(args, "event_location", None) or "steps"
    if args.c_dir:
        out = export_c(args.model, args.c_dir, args.build_dir, progress=progress,
                       sensitivities=bool(sensitivities), event_location=location)
        print(f"C project written to {out}: cd there and run make")
    if args.fmu:
        from .fmu import export_fmu
        out = export_fmu(args.model, args.fmu, args.build_dir, progress=progress,
                         sensitivities=sensitivities, event_location=location)
        print(f"FMU written to {out}")
    return 0
