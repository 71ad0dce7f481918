"""Run settings checked in one place: t_end, dt, output_dt and the method options.

Both solvers call :func:`schedule` and :func:`options_for` (re-exported by
:mod:`fccgen.settings.methods`) with their arguments; the model loader calls them on the model
file's ``simulate`` section with the method's default options, so ``fccgen check``
refuses every setting ``fccgen simulate`` would. Each broken rule raises
:class:`RunSettingError` naming the setting (its flag when it was given, else
``simulate.NAME``), the rule and the value; limits are refused before anything is
allocated, with what to change.
"""
from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

from ..errors import FccgenError, shown
from ..rank import RANK_TOL

EPS = 2.220446049250313e-16          # double precision: spacing of numbers near 1
# A fixed-step run takes at most MAX_STEPS steps (about 2 minutes at 1 us per step, the
# fastest models'; a larger number is almost always a dt typed too small) and records
# at most MAX_OUTPUT_ROWS output times and MAX_OUTPUT_BYTES of numbers (8 bytes each):
# a result is copied a few times on its way to a file, so 1 GiB of record needs a few
# GiB of memory.
MAX_STEPS = 10 ** 8
MAX_OUTPUT_ROWS = 10 ** 7
MAX_OUTPUT_BYTES = 2 ** 30
# t_end, dt and output_dt, like every number of a model file (fccgen.model.fields).
MAX_TIME = 1e12
# RK4's stability polynomial R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24; a mode is stable
# when |R(lambda dt)| <= 1 (within rounding of R's few terms).
RK4_GROWTH_TOLERANCE = 1e-12

# Command-line flag of each setting, for messages about values given there.
FLAGS = {"t_end": "--t-end", "dt": "--dt", "output_dt": "--output-dt", "rtol": "--rtol",
         "atol": "--atol", "alpha": "--baumgarte-alpha", "beta": "--baumgarte-beta"}


def flag(setting: str) -> str:
    return FLAGS.get(setting, f"--method-option {setting}=VALUE")


def interval(low: float, high: float, low_open: bool, high_open: bool) -> str:
    """``(0, 1]``-style text of a range."""
    return f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"


class RunSettingError(FccgenError, ValueError):
    """A run setting (t_end, dt, output_dt or a method option) breaks a rule.

    ``rules`` maps each setting the rule is about to its wording, the likeliest culprit
    first; ``given`` holds the settings the caller gave (command-line flags, API
    arguments), the others came from the model file or the method's defaults. The
    message blames the first setting of ``rules`` that was given, by its name and flag
    (``dt (--dt)``), else the first one as the model file's ``simulate.NAME``. The model loader blames instead
    the first one its file holds (:meth:`culprit`) at that key's line.
    """

    def __init__(self, rules: dict[str, str], values: dict, given=frozenset()):
        self.rules = dict(rules)
        self.values = dict(values)
        self.given = frozenset(given)
        self.setting = self.culprit(self.given)
        self.rule = self.rules[self.setting]
        self.value = self.values.get(self.setting)
        where = (f"{self.setting} ({flag(self.setting)})" if self.setting in self.given
                 else f"simulate.{self.setting}")
        super().__init__(f"{where}: {self.rule} (got {shown(self.value)})")

    def culprit(self, present) -> str:
        """The first setting of the rule in ``present``, else the first one."""
        return next((s for s in self.rules if s in present), next(iter(self.rules)))


@dataclass(frozen=True)
class Schedule:
    """When a run steps and records. Fixed-step methods: n_steps steps of dt (the last
    shortened to end at t_end), a record every ``every`` steps. Adaptive methods: dt is
    the first step (None: automatic) and records come at multiples of output_dt."""
    t_end: float
    dt: float | None
    output_dt: float
    every: int = 1
    n_steps: int = 0
    n_outputs: int = 0            # an upper bound of the recorded times


class Options(dict):
    """A method's options (name -> value) that remembers which ones the caller gave,
    so that a later rule on them and dt blames the right flag."""

    def __init__(self, values: dict, given=frozenset()):
        super().__init__(values)
        self.given = frozenset(given)


def options_for(method, rtol=None, atol=None, given: dict | None = None) -> Options:
    """The method's options: its defaults updated with rtol/atol and ``given``. An
    unknown option raises ValueError listing the method's; a value outside the
    option's range (``Option.accepts``) raises RunSettingError naming its flag."""
    opts = method.defaults()
    given = dict(given or {})
    if rtol is not None:
        given["rtol"] = rtol
    if atol is not None:
        given["atol"] = atol
    table = {o.name: o for o in method.options}
    for key, value in given.items():
        if value is None:
            continue
        if key not in table:
            accepted = ", ".join(opts) or "none"
            raise ValueError(f"method {method.name!r} takes no option {key!r} "
                             f"(its options: {accepted})")
        option = table[key]
        x = _float(value)
        if x is None or not option.accepts(x):
            raise RunSettingError({key: option.rule()}, {key: value}, {key})
        opts[key] = int(x) if option.integer else x
    return Options(opts, {k for k, v in given.items() if v is not None})


def _float(value) -> float | None:
    """``value`` as a float, or None when it is not a number (text, a bool, ...)."""
    if isinstance(value, bool):
        return None
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return None


def schedule(method, defaults, t_end=None, dt=None, output_dt=None,
             options: dict | None = None) -> Schedule:
    """The run's schedule from the arguments, else the model's ``simulate`` section
    (``defaults``: t_end, dt, output_dt and values_per_output, the numbers one output
    row records, 0 when unknown), checked: each time in (0, MAX_TIME], dt <= t_end,
    at most MAX_STEPS steps, output_dt a whole multiple of dt (fixed-step methods), at
    most MAX_OUTPUT_ROWS records of at most MAX_OUTPUT_BYTES; with ``options``, the
    method's limits on dt (:func:`check_step_options`)."""
    args = {"t_end": t_end, "dt": dt, "output_dt": output_dt}
    given = frozenset(k for k, v in args.items() if v is not None)
    values = {"t_end": defaults.t_end if t_end is None else t_end,
              "dt": defaults.dt if dt is None else dt}
    values["output_dt"] = (output_dt if output_dt is not None else defaults.output_dt
                           if defaults.output_dt is not None else values["dt"])

    def refuse(rules: dict[str, str]):
        raise RunSettingError(rules, values, given)

    for name in ("t_end", "dt", "output_dt"):
        x = _float(values[name])
        if x is None or not (math.isfinite(x) and 0 < x <= MAX_TIME):
            refuse({name: f"must be a positive number of at most {MAX_TIME:g}"})
        values[name] = x
    t_end, dt, output_dt = values["t_end"], values["dt"], values["output_dt"]
    if dt > t_end:
        refuse({"dt": f"must be at most t_end = {t_end:g}",
                "t_end": f"must be at least dt = {dt:g}"})
    if method.kind == "adaptive":
        sched = Schedule(t_end, dt if "dt" in given else None, output_dt,
                         n_outputs=_adaptive_outputs(values, refuse))
    else:
        sched = _fixed(values, refuse)
    _check_bytes(sched, getattr(defaults, "values_per_output", 0) or 0, refuse)
    if options is not None:
        check_step_options(method, sched, options,
                           given | getattr(options, "given", frozenset()))
    return sched


def _fixed(values: dict, refuse) -> Schedule:
    """Schedule of a fixed-step method: at most MAX_STEPS steps, output_dt a whole
    multiple of dt, at most MAX_OUTPUT_ROWS records."""
    t_end, dt, output_dt = values["t_end"], values["dt"], values["output_dt"]
    if dt * MAX_STEPS < t_end * (1 - 1e-9):          # t_end / dt > MAX_STEPS
        steps = f"t_end / dt = {t_end / dt:.3g} steps, more than {MAX_STEPS:.0e} in one run"
        refuse({"dt": f"{steps}: use a larger dt (at least {t_end / MAX_STEPS:.3g})",
                "t_end": f"{steps}: use a shorter t_end (at most {dt * MAX_STEPS:.3g})"})
    ratio = output_dt / dt
    every = round(ratio) if math.isfinite(ratio) else 0
    if every < 1 or abs(ratio - every) > 1e-9 * ratio:
        refuse({"output_dt": f"must be a positive whole multiple of dt = {dt!r}",
                "dt": f"must divide output_dt = {output_dt!r} a whole number of times"})
    n_steps = max(1, math.ceil(t_end / dt - 1e-9))
    rows = n_steps // every + 2
    if rows > MAX_OUTPUT_ROWS:
        refuse(_too_many_rows(rows, t_end))
    return Schedule(t_end, dt, output_dt, every, n_steps, rows)


def _adaptive_outputs(values: dict, refuse) -> int:
    """Records of an adaptive method (at multiples of output_dt and t_end)."""
    t_end, output_dt = values["t_end"], values["output_dt"]
    if output_dt * MAX_OUTPUT_ROWS < t_end:
        refuse(_too_many_rows(t_end / output_dt, t_end))
    return math.floor(t_end / output_dt) + 2


def _too_many_rows(rows: float, t_end: float) -> dict[str, str]:
    more = f"{rows:.3g} output times, more than {MAX_OUTPUT_ROWS:.0e}"
    return {"output_dt": f"{more}: use a larger output_dt (at least "
                         f"{t_end / MAX_OUTPUT_ROWS:.3g})",
            "t_end": f"{more}: use a larger output_dt or a shorter t_end"}


def _check_bytes(sched: Schedule, width: int, refuse):
    """At most MAX_OUTPUT_BYTES recorded: outputs x width numbers x 8 bytes."""
    size = sched.n_outputs * width * 8
    if size > MAX_OUTPUT_BYTES:
        most = MAX_OUTPUT_BYTES // (width * 8)
        more = (f"{sched.n_outputs} output times of {width} numbers are "
                f"{size / 2 ** 30:.3g} GiB, more than {MAX_OUTPUT_BYTES / 2 ** 30:g} GiB")
        refuse({"output_dt": f"{more}: use a larger output_dt (at least "
                             f"{sched.t_end / most:.3g})",
                "t_end": f"{more}: use a larger output_dt or a shorter t_end"})


def check_step_options(method, sched: Schedule, options: dict, given=frozenset()):
    """The limits a method's options put on its step dt.

    baumgarte: the constraint error obeys e'' + 2 alpha e' + beta^2 e = 0, whose modes
    lambda = -alpha +- sqrt(alpha^2 - beta^2) RK4 integrates stably only when
    |R(lambda dt)| <= 1 (on the real axis: lambda dt >= -2.785).
    ali3p: the Newton matrix is M + (dt^2/4) penalty m_ref B^T B / ||B||^2 (per row);
    once (dt^2/4) penalty >= 1/eps the mass matrix is lost in its rounding.
    """
    if sched.dt is None:
        return
    dt = sched.dt
    values = {"dt": dt, **options}
    if method.name == "baumgarte":
        alpha, beta = options["alpha"], options["beta"]
        growth = max(rk4_growth(lam * dt) for lam in baumgarte_modes(alpha, beta))
        if growth > 1 + RK4_GROWTH_TOLERANCE:
            limit = _largest_stable_dt(alpha, beta, dt)
            why = (f"RK4 is unstable on the Baumgarte modes of alpha = {alpha:g}, beta = "
                   f"{beta:g} at dt = {dt:g} (|R(lambda dt)| = {growth:.3g} > 1)")
            raise RunSettingError(
                {"dt": f"{why}: use dt <= {limit:.3g} or smaller alpha and beta",
                 "alpha": f"{why}: use smaller alpha and beta, or dt <= {limit:.3g}",
                 "beta": f"{why}: use smaller alpha and beta, or dt <= {limit:.3g}"},
                values, given)
    if method.name == "ali3p":
        scaled = dt * dt / 4 * options["penalty"]
        if scaled >= 1 / EPS:
            why = (f"(dt^2/4) penalty = {scaled:.3g} is at least 1/eps = {1 / EPS:.3g}: "
                   "the mass matrix is lost in the rounding of ALI3-P's Newton matrix")
            raise RunSettingError({"penalty": f"{why}: use a smaller penalty",
                                   "dt": f"{why}: use a smaller dt or penalty"},
                                  values, given)


def rk4_growth(z: complex) -> float:
    """|R(z)| of RK4: the factor a mode lambda grows by in one step, z = lambda dt."""
    return abs(1 + z + z * z / 2 + z ** 3 / 6 + z ** 4 / 24)


def baumgarte_modes(alpha: float, beta: float) -> tuple[complex, complex]:
    """Roots of lambda^2 + 2 alpha lambda + beta^2 = 0."""
    root = cmath.sqrt(alpha * alpha - beta * beta)
    return (-alpha + root, -alpha - root)


def _largest_stable_dt(alpha: float, beta: float, dt: float) -> float:
    """The step below which RK4 is stable on the Baumgarte modes (bisection on
    [0, dt]; the stable steps of a mode in the left half-plane are an interval)."""
    lo, hi = 0.0, dt
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if max(rk4_growth(lam * mid) for lam in baumgarte_modes(alpha, beta)) \
                <= 1 + RK4_GROWTH_TOLERANCE:
            lo = mid
        else:
            hi = mid
    return lo


# The solvers' tolerances when neither the caller nor the model's simulate section
# gives them (docs/reliability.md: the rank decision and the projections).
# RANK_TOL (fccgen.rank): QR pivot ratio at or below which a row is lost (singular position)
POSITION_TOL = 1e-11      # Newton projection, times the largest body length
MAX_NEWTON = 20           # Newton iterations of one position projection


def solver_tolerances(defaults, length_scale: float, rank_tol=None, position_tol=None,
                      max_newton=None) -> tuple[float, float, int]:
    """(rank_tol, position_tol, max_newton): each from the argument, else the model's
    ``simulate`` section (``defaults``), else the defaults above (position_tol:
    POSITION_TOL times ``length_scale``)."""
    def pick(given, key):
        return given if given is not None else getattr(defaults, key, None)
    rank_tol = pick(rank_tol, "rank_tol")
    position_tol = pick(position_tol, "position_tol")
    max_newton = pick(max_newton, "max_newton")
    return (RANK_TOL if rank_tol is None else float(rank_tol),
            POSITION_TOL * length_scale if position_tol is None else float(position_tol),
            MAX_NEWTON if max_newton is None else int(max_newton))


# The compiled runtime's linear solver (fccgen.runtime.paths): "dense" (pivoted QR of B
# and a null-space basis), "sparse" (LDL^T of M + B^T alpha B over a pattern fixed at
# load time), or "auto": sparse from fccgen.runtime.paths.SPARSE_MIN_COORDINATES on,
# and below where each run's rank decision shows it well posed (paths.small_model_path).
LINEAR_SOLVERS = ("auto", "dense", "sparse")


def linear_solver_choice(defaults, given=None) -> str:
    """The linear solver from the argument, else the model's ``simulate`` section
    (``defaults``), else "auto"; ValueError for a name not in LINEAR_SOLVERS."""
    name = given if given is not None else getattr(defaults, "linear_solver", None)
    name = "auto" if name is None else name
    if name not in LINEAR_SOLVERS:
        raise ValueError(f"linear_solver must be one of {', '.join(LINEAR_SOLVERS)} "
                         f"(got {name!r})")
    return name
