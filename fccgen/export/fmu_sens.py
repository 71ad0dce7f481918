"""The sensitivities' outputs of an FMU (``fccgen export MODEL.yaml --fmu FILE.fmu
--sensitivities [KEYS]``, docs/export.md "Sensitivities in the FMU").

FMI 2.0 has no call for a derivative with respect to a parameter over a run
(``fmi2GetDirectionalDerivative`` is with respect to states and inputs at one
instant), so the keys are chosen at export and each derivative is an output of its
own: ``d(COLUMN)/d(KEY)`` for every output column but ``constraint_error``, and for a
model with events ``d(events.last.time)/d(KEY)``, the derivative of the latest
event's time. They are the C project's sensitivities (``NAME_sensitivity``,
``NAME_event_sensitivity``), asked for at every start of the run. Their value
references follow the event outputs (or the inputs), key by key.
"""
from __future__ import annotations

from dataclasses import dataclass

from .c_project import ExportError

NO_SENSITIVITY = ("constraint_error",)      # the C API refuses its derivative
EVENT_TIME = "events.last.time"


@dataclass(frozen=True)
class SensOutput:
    column: str      # an output column, or EVENT_TIME
    key: str         # a with_parameters key
    row: int         # NAME_sensitivity's output index, or -1: the latest event's time

    @property
    def name(self) -> str:
        return f"d({self.column})/d({self.key})"

    @property
    def description(self) -> str:
        what = ("the latest event's time" if self.row < 0 else self.column)
        return f"the derivative of {what} with respect to the parameter {self.key}"


def chosen_keys(model_path, project, sensitivities) -> list[str]:
    """The keys whose sensitivities the FMU outputs: none (sensitivities falsy), every
    key the export gives one (True), or the ones named (a list, or a text of keys
    separated by commas), each checked against those."""
    if not sensitivities:
        return []
    have = list(project.sensitivities or [])
    if sensitivities is True:
        return have
    if isinstance(sensitivities, str):
        sensitivities = [k.strip() for k in sensitivities.split(",")]
    chosen = []
    for key in sensitivities:
        if key not in have:
            known = {k for k, _, _ in project.keys}
            why = ("is not a parameter of the model" if key not in known
                   else "has no sensitivity in the export")
            raise ExportError(f"{model_path}: --sensitivities: {key!r} {why}; the keys "
                              f"with one: {', '.join(have) or '(none)'}")
        if key not in chosen:
            chosen.append(key)
    if not chosen:
        raise ExportError(f"{model_path}: --sensitivities names no key")
    return chosen


def per_key_rows(columns, has_events: bool, forces=()) -> list[int]:
    """What each key's outputs read, in order: output indices, then -1 (the latest
    event's time) for a model with events. forces: the driver-force columns, which
    have no sensitivity (as in fccgen simulate)."""
    rows = [k for k, c in enumerate(columns) if c not in NO_SENSITIVITY
            and c not in forces]
    return rows + ([-1] if has_events else [])


def sensitivity_outputs(columns, keys, has_events: bool, forces=()) -> list[SensOutput]:
    """The FMU's sensitivity outputs in value-reference order (key-major)."""
    rows = per_key_rows(columns, has_events, forces)
    return [SensOutput(EVENT_TIME if r < 0 else columns[r], key, r)
            for key in keys for r in rows]
