"""The rank of the constraint Jacobian is decided once per run and kept (fccgen.rank):
a redundant mechanism must never freeze, and a change of its degrees of freedom must
be said, not hidden."""
from __future__ import annotations

import numpy as np
import pytest

import bricard
import fccgen
from fccgen import rank as rank_rule
from fccgen.diagnostics.check import check_model
from fccgen.errors import RunWarning, SimulationError
from fccgen.runtime._solve import constrained_solve
from fccgen.runtime import setup_reuse

FLAT_FOUR_BAR = """
name: flat_four_bar
points:
  O: {at: [0, 0, 0], fixed: true}
  A: {at: [2, 0, 0], fixed: true}
  P: [1, 0, 0]
  Q: [3, 0, 0]
vectors:
  z: {along: [0, 0, 1], fixed: true}
bodies:
  crank: {points: [O, P], vector: z, mass: 1.0, center: [0.5, 0, 0],
          inertia: [1.0e-4, 0.0834, 0.0834]}
  coupler: {points: [P, Q], vector: z, mass: 1.0, center: [1.0, 0, 0],
            inertia: [1.0e-4, 0.334, 0.334]}
  rocker: {points: [A, Q], vector: z, mass: 1.0, center: [0.5, 0, 0],
           inertia: [1.0e-4, 0.0834, 0.0834]}
initial:
  points: {P: [0, 1, 0], Q: [0, 1, 0]}
simulate: {t_end: 1.0, dt: 1.0e-3}
"""


def near_flat_four_bar(eps: float) -> str:
    """FLAT_FOUR_BAR with its crank eps rad above the flat position."""
    c, s = float(np.cos(eps)), float(np.sin(eps))
    return (FLAT_FOUR_BAR.replace("name: flat_four_bar", "name: near_flat")
            .replace("P: [1, 0, 0]", f"P: [{c!r}, {s!r}, 0]")
            .replace("Q: [3, 0, 0]", f"Q: [{2 + c!r}, {s!r}, 0]"))


@pytest.fixture(scope="module")
def bricard_solvers(tmp_path_factory, build_dir):
    folder = tmp_path_factory.mktemp("bricard")
    out = {}
    for encoding in ("line", "distance"):
        path = folder / f"bricard_{encoding}.yaml"
        path.write_text(bricard.text(encoding))
        out[encoding] = fccgen.load(path, build_dir)
    return out


@pytest.fixture(scope="module")
def bricard_reference(bricard_solvers):
    """P3 over 10 s from ALI3-P, which makes no rank decision (augmented Lagrangian),
    at dt = 1e-3 and 5e-4, Richardson-extrapolated for its second order. The two
    steps differ by 2.4e-6 m at most; the extrapolation error is below 1e-7 m (the
    extrapolated value agrees with RK4 at 1 ms to 2e-8 m at t = 10 s when measured)."""
    s = bricard_solvers["distance"]
    runs = [s.simulate(t_end=10.0, dt=dt, output_dt=0.05, method="ali3p")
            for dt in (1e-3, 5e-4)]
    p3 = [np.column_stack([r["P3.x"], r["P3.y"], r["P3.z"]]) for r in runs]
    return runs[1].t, p3[1] + (p3[1] - p3[0]) / 3.0


@pytest.mark.parametrize("encoding", ["line", "distance"])
def test_bricard_follows_its_motion_under_the_default_simulate(
        bricard_solvers, bricard_reference, encoding):
    """Default method (rk4, dt 1 ms, projection), 10 s: P3 within 1e-6 m of the
    reference at every output (RK4's global error here is ~2e-7 m), one degree of
    freedom throughout, energy kept to 1e-6 J (measured 2-4e-7 J) and no warning."""
    t_ref, p3_ref = bricard_reference
    result = bricard_solvers[encoding].simulate(t_end=10.0, output_dt=0.05)
    assert np.allclose(result.t, t_ref, atol=1e-12)
    p3 = np.column_stack([result["P3.x"], result["P3.y"], result["P3.z"]])
    assert np.ptp(p3[:, 0]) > 1.5                  # it moves: P3.x swings over ~1.8 m
    assert np.max(np.abs(p3 - p3_ref)) < 1e-6
    assert result.info["dof"] == 1 and result.info["final_dof"] == 1
    assert result.info["dof_changes"] == [] and result.info["warnings"] == []
    assert result.info["energy_drift"] < 1e-6


@pytest.mark.parametrize("encoding", ["line", "distance"])
def test_bricard_check_reports_one_dof(tmp_path, encoding):
    path = tmp_path / f"bricard_{encoding}.yaml"
    path.write_text(bricard.text(encoding))
    report = check_model(path)
    assert report.n_q == 24 and report.dof == 1


def test_leaving_a_singular_start_is_reported_as_a_dof_change(tmp_path, build_dir):
    """A four-bar (links 1, 2, 1 on a ground of 2) released from its flat position:
    there the Jacobian has rank 4 (2 DOF); once it moves, rank 5 (1 DOF). The run
    follows the parallelogram branch P.y = sin(t) (P and Q given the same speed) and
    says when the degrees of freedom changed."""
    path = tmp_path / "flat_four_bar.yaml"
    path.write_text(FLAT_FOUR_BAR)
    solver = fccgen.load(path, build_dir)
    with pytest.warns(RunWarning, match="changed from 2 to 1 at t = 0.001"):
        result = solver.simulate(t_end=1.0, output_dt=0.1)
    assert result.info["dof"] == 2 and result.info["final_dof"] == 1
    assert result.info["dof_changes"] == [dict(t=0.001, dof_before=2, dof_after=1)]
    # crank angle theta: P = (cos, sin); v0 = 1 at unit length: theta = t (no gravity)
    assert np.allclose(result["P.y"], np.sin(result.t), atol=1e-9)
    assert any("changed from 2 to 1" in w for w in result.info["warnings"])


def test_numeric_solver_makes_the_same_decisions(tmp_path):
    path = tmp_path / "flat_four_bar.yaml"
    path.write_text(FLAT_FOUR_BAR)
    solver = fccgen.load_numeric(path)
    with pytest.warns(RunWarning, match="changed from 2 to 1 at t = 0.001"):
        result = solver.simulate(t_end=0.05, output_dt=0.01)
    assert result.info["dof_changes"] == [dict(t=0.001, dof_before=2, dof_after=1)]


def test_svd_gap_decision_and_its_uncertain_band():
    """Rows scaled to unit length; sigma ratios above 1e-8 count, ratios in
    [1e-10, 1e-6] are reported as uncertain."""
    rng = np.random.default_rng(3)
    U, _ = np.linalg.qr(rng.normal(size=(5, 5)))
    V, _ = np.linalg.qr(rng.normal(size=(7, 7)))
    for smallest, rank, uncertain in ((1e-3, 5, 0), (1e-7, 5, 1), (1e-9, 4, 1),
                                      (1e-14, 4, 0)):
        B = U @ np.diag([1.0, 0.8, 0.5, 0.3, smallest]) @ V[:5]
        d = rank_rule.decide(B * np.array([1, 1e3, 1e-3, 2, 5])[:, None])
        assert d.rank == rank, smallest
        assert len(d.uncertain) == uncertain, smallest


def test_kept_rank_overrides_a_large_spurious_pivot():
    """B with a redundant row perturbed by 1e-7 (a QR pivot far above 1e-10): the pivot
    threshold alone counts it, the kept rank does not, and the solution then satisfies
    the unperturbed constraints in the least-squares sense."""
    rng = np.random.default_rng(7)
    n = 8
    B = rng.normal(size=(4, n))
    B = np.vstack([B, B[0] + B[1] + 1e-7 * rng.normal(size=n)])
    A = rng.normal(size=(n, n))
    M, Q = A @ A.T + n * np.eye(n), rng.normal(size=n)
    _, rank_threshold = constrained_solve(M, B, Q, np.zeros(5))
    _, rank_kept = constrained_solve(M, B, Q, np.zeros(5), rank=4)
    assert (rank_threshold, rank_kept) == (5, 4)


def test_a_model_that_cannot_move_is_said_so(tmp_path, build_dir):
    path = tmp_path / "locked.yaml"
    path.write_text(FLAT_FOUR_BAR.replace("name: flat_four_bar", "name: locked")
                    .replace("initial:\n  points: {P: [0, 1, 0], Q: [0, 1, 0]}\n", "")
                    .replace("P: [1, 0, 0]", "P: [0.6, 0.8, 0]")
                    .replace("Q: [3, 0, 0]", "Q: [2.6, 0.8, 0]")
                    .replace("A: {at: [2, 0, 0]", "A: {at: [2, 0, 0]")
                    .replace("bodies:", "constraints:\n  - {type: distance, points: [O, Q], "
                             "length: 2.7202941017470885}\nbodies:"))
    solver = fccgen.load(path, build_dir)
    with pytest.warns(RunWarning, match="0 degrees of freedom"):
        result = solver.simulate(t_end=0.01)
    assert result.info["dof"] == 0


def test_cli_shows_the_dof_change_and_takes_the_solver_tolerances(tmp_path, build_dir,
                                                                    capsys):
    from fccgen.cli import main
    path = tmp_path / "flat_four_bar.yaml"
    path.write_text(FLAT_FOUR_BAR)
    common = ["simulate", str(path), "--build-dir", str(build_dir), "-q", "--t-end", "0.1"]
    assert main([*common, "--rank-tol", "1e-9", "--position-tol", "1e-12",
                 "--max-newton", "5"]) == 0
    out, err = capsys.readouterr()
    assert "degrees of freedom 2 by rank, 1 at the end" in out
    assert "fccgen: warning: the degrees of freedom changed from 2 to 1" in err
    for flag, value in (("--rank-tol", "2"), ("--position-tol", "0"), ("--max-newton", "0")):
        assert main([*common, flag, value]) == 1
        assert f"{flag} must be" in capsys.readouterr().err


def test_a_projection_that_kills_the_motion_is_flagged(bricard_solvers, monkeypatch):
    """The independent check of the rank: force the old miscount (rank 24 of 24
    coordinates on Bricard: 0 DOF). The first step moves the linkage, the velocity
    projection removes all of that kinetic energy, and the run says so, although its
    energy and constraint figures look perfect (the symptom of the old freeze). A
    solver with nothing kept: the fixture's keeps the decisions of earlier runs
    (fccgen.runtime.setup_reuse), which the miscount would not reach."""
    solver = bricard_solvers["line"].with_parameters({})
    setup_reuse.forget()              # nor the decisions kept for every solver
    real = rank_rule.decide

    def miscount(B, n_q=None, groups=None, **options):
        d = real(B, n_q, groups, **options)
        return rank_rule.RankDecision(d.rank + 1, d.n_q, d.sigma)

    monkeypatch.setattr(rank_rule, "decide", miscount)
    with pytest.warns(RunWarning) as record:
        result = solver.simulate(t_end=0.01)
    texts = [str(w.message) for w in record]
    assert any("removed 100% of the kinetic energy at t = 0.001" in t for t in texts), texts
    assert result.info["projection_energy_cut"] > 0.99
    assert result.info["energy_drift"] < 1e-5   # 6.4e-6 J of E0 = -29 J: looked right


def test_solver_tolerances_come_from_the_model_file_unless_given(tmp_path):
    path = tmp_path / "tolerances.yaml"
    path.write_text(FLAT_FOUR_BAR.replace(
        "simulate: {t_end: 1.0, dt: 1.0e-3}",
        "simulate: {t_end: 1.0, dt: 1.0e-3, rank_tol: 1.0e-9, position_tol: 1.0e-12, "
        "max_newton: 7}"))
    solver = fccgen.load_numeric(path)
    assert (solver.rank_tol, solver.position_tol, solver.max_newton) == (1e-9, 1e-12, 7)
    solver = fccgen.load_numeric(path, max_newton=3)
    assert solver.max_newton == 3 and solver.rank_tol == 1e-9


@pytest.mark.parametrize("key, value, rule", [
    ("rank_tol", "2", "must be a number in (0, 1)"),
    ("position_tol", "-1", "must be a positive number"),
    ("max_newton", "2.5", "must be a whole number in [1, 1000]"),
])
def test_bad_solver_tolerances_in_the_model_file(tmp_path, key, value, rule):
    from fccgen.errors import ModelError
    path = tmp_path / "bad.yaml"
    path.write_text(FLAT_FOUR_BAR.replace("simulate: {t_end: 1.0, dt: 1.0e-3}",
                                          f"simulate: {{t_end: 1.0, {key}: {value}}}"))
    with pytest.raises(ModelError) as info:
        fccgen.load_numeric(path)
    text = str(info.value)
    assert f"bad.yaml:19: simulate.{key}: {rule}" in text and f"(got {value})" in text, text


def test_a_start_near_a_singular_position_is_called_uncertain(tmp_path, build_dir):
    """The four-bar as a parallelogram 1e-8 rad from flat: the singular value that
    vanishes at the flat position is ~1e-8 of the largest, inside [1e-10, 1e-6].
    check says the decision is uncertain and a run warns about it (then, leaving the
    position, the run also reports its change from 2 to 1 degree of freedom)."""
    path = tmp_path / "near_flat.yaml"
    path.write_text(near_flat_four_bar(1e-8))
    report = check_model(path)
    assert report.uncertain and all(1e-10 <= x <= 1e-6 for x in report.uncertain)
    assert "UNCERTAIN" in report.text()
    with pytest.warns(RunWarning) as record:        # and, as it moves away, a DOF change
        fccgen.load(path, build_dir).simulate(t_end=0.01)
    assert any("close to a singular position" in str(w.message) for w in record)
