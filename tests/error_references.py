"""References for the error-target tests (tests/test_error_target.py) and their
grid search (tests/data/error_target_grid.py): each case's model, run settings,
and a function that gives a run's true error, independent of the runs it judges.

- A01, the IFToMM pendulum over 2000 s: the closed form of the simple pendulum
  (Jacobi elliptic functions), which matches the published table to its six digits.
- A02, the N-four-bar (N = 40) over 20 s: the published table of B0 (ADAMS, six
  digits), so only the 1e-3 level is judged against it. Past its singular (flat)
  positions fccgen's own runs do not converge below about 1e-4 m as the step shrinks
  (benchmarks/a02_convergence.py, docs/accuracy.md), so no converged run can judge
  1e-6 over 20 s.
- A02 over its first 0.6 s, before the first flat position at t = 0.72 s ("a02s"):
  a run of dopri5 at rtol 1e-13, which rk4 at dt = 2.5e-4 meets to 9e-14 m (every
  moving point, measured) and dopri5 at 1e-12 to 3.5e-13 m.
- The heavy (Lagrange) top at 150 rad/s for 0.5 s: its Euler-angle equations
  (tests/minimal.py) integrated by SciPy's DOP853 at rtol 1e-13.
- The solar array with two latches over 3 s: a fine run of dopri5 at rtol 1e-12
  (checked against rk4 at dt = 1e-4: 7e-13 m apart, latch times 1e-12 s apart).
- Andrews' squeezing mechanism over 0.03 s: its published equations in seven angles
  (tests/andrews_reference.py) integrated by SciPy's DOP853 at rtol 1e-13, which
  meets the published solution at t = 0.03 to 8e-12 m; the compared points are the
  moving joint points F, E, G, H (and E4, E6, the same place on bodies 4 and 6).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = ROOT / "tests" / "reference"

TOP = dict(m=15.0, d=0.15, L=0.3, It=0.08, Ia=0.1, g=9.81)


def pendulum_exact(t, L=1.0, g=9.81):
    """(x, y) of the A01 pendulum: released at rest from the horizontal (x = -L),
    theta from the downward vertical. With k = sin(theta0 / 2) = sin(pi / 4), the
    closed form is sin(theta / 2) = -k sn(K - w t | k^2), w = sqrt(g / L) (Lawden,
    Elliptic Functions and Applications, 1989, ch. 5), the argument reduced modulo
    the period 4K before evaluation."""
    from scipy.special import ellipj, ellipk
    k = math.sin(math.pi / 4)
    K = ellipk(k * k)
    u = np.mod(K - math.sqrt(g / L) * np.asarray(t, float), 4 * K)
    sn = ellipj(u, k * k)[0]
    theta = -2 * np.arcsin(k * sn)
    return L * np.sin(theta), -L * np.cos(theta)


def top_axis():
    """The top's symmetry axis at the start: 30 degrees from the vertical."""
    a = math.radians(30.0)
    return np.array([math.sin(a), 0.0, math.cos(a)])


def top_model() -> str:
    """The heavy top of tests/test_extremes_dynamics.py: spin 150 rad/s about an axis
    30 degrees from the vertical, plus 1 rad/s about the vertical."""
    import test_extremes_models as em
    axis = top_axis()
    return em.axisymmetric_top(TOP["L"] * axis, [0, 1, 0], TOP["m"], TOP["d"], TOP["Ia"],
                               TOP["It"], 150.0 * axis + [0.0, 0.0, 1.0])


def top_tip(solver, t):
    """The tip P of the Lagrange top at times t from its Euler-angle equations."""
    from scipy.integrate import solve_ivp

    import minimal
    init = solver.initial_state()
    w0 = solver.body_outputs(init.q, init.v)[0, 3:]
    sol = solve_ivp(minimal._top_rhs(TOP), (t[0], t[-1]), minimal.top_state(top_axis(), w0),
                    method="DOP853", t_eval=t, rtol=1e-13, atol=1e-15)
    assert sol.status == 0, sol.message
    e, _ = minimal.top_axis_and_omega(sol.y.T)
    return TOP["L"] * e


@dataclass
class Case:
    name: str
    t_end: float
    output_dt: float
    levels: tuple
    reference_rtol: float = 1e-12     # of the fine dopri5 run, where that is the reference

    def error(self, solver, result, ref) -> float:
        """The true error of a run (largest distance over its output times)."""
        if self.name == "a01":
            x, y = ref
            return float(np.max(np.hypot(result["P.x"] - x, result["P.y"] - y)))
        if self.name == "a02":
            return ref.error(result)[0]
        if self.name == "andrews":
            return andrews_error(result, ref)
        if self.name == "top":
            P = np.column_stack([result[f"P.{c}"] for c in "xyz"])
            return float(np.max(np.linalg.norm(P - ref, axis=1)))
        from fccgen.target_error.compare import compared, distance
        return float(np.max(distance(result, ref, compared(solver.plan,
                                                           solver.length_scale),
                                     self.t_end)[1]))

    def reference(self, solver):
        t = np.arange(0.0, self.t_end + self.output_dt / 2, self.output_dt)
        if self.name == "a01":
            return pendulum_exact(t)
        if self.name == "a02":
            from fccgen.bench.accuracy import reference_from_table
            return reference_from_table(REFERENCE / "mbsbenchmark_A02_solution_data_B0.csv",
                                        "B0")
        if self.name == "top":
            return top_tip(solver, t)
        if self.name == "andrews":
            import andrews_reference as andrews
            return t, [andrews.points(y[:7]) for y in andrews.solve(t)]
        return solver.simulate(method="dopri5", rtol=self.reference_rtol,
                               atol=self.reference_rtol * 1e-3,
                               t_end=self.t_end, output_dt=self.output_dt,
                               reactions=False)


CASES = {
    "a01": Case("a01", 2000.0, 0.5, (1e-3, 1e-6)),
    "a02": Case("a02", 20.0, 0.05, (1e-3,)),
    "top": Case("top", 0.5, 0.01, (1e-3, 1e-6, 1e-9)),
    "solar": Case("solar", 3.0, 0.01, (1e-3, 1e-6, 1e-9)),
    "andrews": Case("andrews", 0.03, 3e-4, (1e-3, 1e-6, 1e-9)),
    "a02s": Case("a02s", 0.6, 0.05, (1e-6, 1e-9), reference_rtol=1e-13),
}
ANDREWS_POINTS = ("F", "E", "G", "E4", "H", "E6")   # the model's moving points


def andrews_error(result, ref) -> float:
    """Largest distance of the Andrews model's moving points from where the published
    equations put them, over the output times the run shares with the reference."""
    t_ref, points = ref
    k = np.searchsorted(t_ref, np.asarray(result.t) - 1e-12)
    assert np.allclose(t_ref[k], result.t, rtol=0, atol=1e-12)
    worst = 0.0
    for name in ANDREWS_POINTS:
        ours = np.column_stack([result[f"{name}.x"], result[f"{name}.y"]])
        theirs = np.array([points[i][name] for i in k])
        worst = max(worst, float(np.max(np.linalg.norm(ours - theirs, axis=1))))
    return worst


def load(name: str, build_dir, model_dir):
    """The compiled solver of a case (the top's model file is written to model_dir)."""
    import fccgen
    if name == "top":
        import test_extremes_models as em
        return em.make_loader(Path(model_dir), build_dir)(top_model())
    file = {"a01": "a01_pendulum", "a02": "a02_n_four_bar", "a02s": "a02_n_four_bar",
            "solar": "solar_array", "andrews": "andrews"}[name]
    return fccgen.load(ROOT / "examples" / f"{file}.yaml", build_dir)
