"""The ``fccgen export`` command (fccgen/cli.py hands it over)."""
from __future__ import annotations


def run_export(args, progress) -> int:
    from .c_project import ExportError, export_c
    if not args.c_dir and not args.fmu:
        raise ExportError("say what to write: --c DIR (a C project) or --fmu FILE.fmu")
    if getattr(args, "sensitivities", False) and not args.c_dir:
        raise ExportError("--sensitivities goes with --c DIR: the FMU carries none "
                          "(docs/export.md, \"Sensitivities\")")
    if args.c_dir:
        out = export_c(args.model, args.c_dir, args.build_dir, progress=progress,
                       sensitivities=getattr(args, "sensitivities", False))
        print(f"C project written to {out}: cd there and run make")
    if args.fmu:
        from .fmu import export_fmu
        out = export_fmu(args.model, args.fmu, args.build_dir, progress=progress)
        print(f"FMU written to {out}")
    return 0
