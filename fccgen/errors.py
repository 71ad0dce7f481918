"""Errors that fccgen raises for bad input and failed builds or simulations."""
from __future__ import annotations


class FccgenError(Exception):
    """Base class of every error fccgen raises on purpose."""


# Longest text of a value, an item path and a rule in a message: a message stays below
# a few kB whatever the file holds (a megabyte-long scalar, a key of any length).
SHOWN_VALUE_CHARS = 200
SHOWN_ITEM_CHARS = 300
SHOWN_RULE_CHARS = 1000


def clip(text: str, limit: int) -> str:
    """``text`` cut to ``limit`` characters, saying how long it was."""
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text)} characters)"


def shown(value) -> str:
    """repr of a value as a message shows it, at most SHOWN_VALUE_CHARS long."""
    try:
        text = repr(value)
    except ValueError:      # an int too long for str() (sys.set_int_max_str_digits)
        text = _long_int_repr(value)
    return clip(text, SHOWN_VALUE_CHARS)


def _long_int_repr(value) -> str:
    """repr that writes an integer too long for str() as its number of digits."""
    if isinstance(value, int):
        try:
            return repr(value)
        except ValueError:
            digits = int(value.bit_length() * 0.30102999566) + 1   # log10(2)
            return f"<an integer of about {digits} digits>"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k!r}: {_long_int_repr(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_long_int_repr(v) for v in value) + "]"
    return repr(value)


class ModelError(FccgenError, ValueError):
    """A model file breaks a rule.

    The message is one sentence: where (file and line), the item, the rule broken and
    the value seen, e.g. ``pendulum.yaml:12: bodies.arm.mass: must be a positive
    number (got -1.0)``. The value, item and rule are shown cut to SHOWN_*_CHARS (the
    attributes keep them whole).
    """

    def __init__(self, file: str, line: int | None, item: str, rule: str, value=None,
                 *, show_value: bool = True):
        self.file = file
        self.line = line
        self.item = item
        self.rule = rule
        self.value = value
        super().__init__(located_text(file, line, item, rule, value, show_value))


def shown_path(path, limit: int = SHOWN_ITEM_CHARS) -> str:
    """A path as a message shows it: whole up to ``limit`` characters, else its end
    (the file's own name) after how long it was."""
    text = str(path)
    if len(text) <= limit:
        return text
    return f"({len(text)} characters) ...{text[-limit:]}"


def os_reason(exc: OSError) -> str:
    """Why an OSError happened, in the user's words: a name or path too long for the
    file system says so and what to do, rather than the system's "File name too
    long"."""
    import errno as codes
    if exc.errno == codes.ENAMETOOLONG:
        return ("its path is longer than the file system allows (at most 255 bytes a "
                "folder or file name, 4096 the whole path); use a shorter name or folder")
    return exc.strerror or str(exc)


def located_text(file, line, item: str, rule: str, value=None, show_value: bool = True):
    """``file:line: item: rule (got value)``, cut as ModelError's message is."""
    file = shown_path(file)
    where = f"{file}:{line}" if line is not None else f"{file}"
    text = f"{where}: {clip(item, SHOWN_ITEM_CHARS)}: {clip(rule, SHOWN_RULE_CHARS)}"
    if show_value:
        text += f" (got {shown(value)})"
    return text


class BuildError(FccgenError, RuntimeError):
    """Generating or compiling a model's kernels failed; the message holds the
    compiler's own output."""


class SimulationError(FccgenError, RuntimeError):
    """A simulation cannot go on (singular mass matrix on the constraint manifold,
    failed assembly, non-finite state).

    :meth:`located` makes one that names the model item it comes from as a ModelError
    does (``file``, ``line``, ``item``, ``rule``, ``value``; fccgen.runs.locate)."""

    file = line = item = rule = value = None

    @classmethod
    def located(cls, file, line, item: str, rule: str, value=None, *,
                show_value: bool = True):
        """``file:line: item: rule (got value)``, with those attributes set."""
        out = cls(located_text(file, line, item, rule, value, show_value))
        out.file, out.line, out.item, out.rule, out.value = file, line, item, rule, value
        return out


class HostError(FccgenError, RuntimeError):
    """The machine cannot do what was asked, whatever the model: a folder that cannot
    be written, a full disk, no C compiler. The message says what to do about it;
    ``errno`` is the operating system's error number when there is one."""

    def __init__(self, message: str, errno: int | None = None):
        super().__init__(message)
        self.errno = errno

    @classmethod
    def from_os_error(cls, exc: OSError, doing: str, path, option: str | None = None,
                      *, name_file: bool = True):
        """One paragraph for an OSError met while ``doing`` something to ``path``:
        what went wrong, then what to do (``option``: the command-line option that
        chooses another place, e.g. ``--build-dir``). ``name_file``: name the file
        the error is about, if it says, rather than ``path`` (False when that file
        is an internal temporary one)."""
        import errno as codes

        elsewhere = f" or choose another place with {option}" if option else ""
        reason = exc.strerror or str(exc)
        if exc.errno in (codes.EACCES, codes.EPERM, codes.EROFS):
            advice = f"make it writable{elsewhere}"
        elif exc.errno in (codes.ENOSPC, codes.EDQUOT):
            reason = "no space left on the device (or the disk quota is used up)"
            advice = f"free some space{elsewhere}"
        elif exc.errno in (codes.ENOTDIR, codes.EEXIST, codes.EISDIR):
            advice = f"a file or folder of that name is in the way: move it{elsewhere}"
        elif exc.errno == codes.ENAMETOOLONG:
            reason = ("the path is longer than the file system allows (at most 255 bytes "
                      "a folder or file name, 4096 the whole path)")
            advice = f"use a shorter name or folder{elsewhere}"
        else:
            advice = f"check the path{elsewhere}"
        where = shown_path(exc.filename if (name_file and exc.filename is not None)
                           else path)
        return cls(f"cannot {doing} {where}: {reason}. To fix it, {advice}.",
                   errno=exc.errno)


class CacheRepairWarning(UserWarning):
    """A cached module was damaged, incomplete or built for another structure, and is
    being rebuilt; the message names the folder and what was wrong."""


class PartialResultWarning(UserWarning):
    """A result file loaded is the partial result of a run that did not finish."""


class ResultMetadataWarning(UserWarning):
    """A result file's metadata (a CSV's sidecar) are unreadable or describe another
    version of the file; the result is loaded without them."""


class RunWarning(UserWarning):
    """A run finished but something in it needs the user's attention (a change of the
    degrees of freedom, a start near a singular position, a model that cannot move).
    The same texts are in ``result.info["warnings"]``."""
