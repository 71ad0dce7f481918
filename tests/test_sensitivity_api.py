"""The sensitivities' interface: what is refused (each with its sentence), the result's
sensitivity(), the files, and `fccgen sensitivity`."""
from __future__ import annotations

import numpy as np
import pytest

import fccgen

from conftest import EXAMPLES

from fccgen.cli import main
from fccgen.errors import ModelError
from fccgen.results import Result

RUN = dict(t_end=0.05, dt=1e-3, method="rk4", reactions=False)


@pytest.fixture(scope="session")
def pendulum(compiled):
    return compiled("double_pendulum")


@pytest.fixture(scope="session")
def with_sens(pendulum):
    return pendulum.simulate(**RUN, sensitivities=["bodies.rod1.mass", "gravity[1]"])


@pytest.mark.parametrize("key, words", [
    ("bodies.rod1.mas", "is not a number fccgen can set"),
    ("simulate.dt", "is a setting of the run"),
    ("vectors.z.along[0]", "unit vector"),
    ("bodies.rod1.center", "add its component [k]"),
    ("bodies.rod1.inertia", "per component"),
    ("bodies.rod1.center[1]", "structural zero"),
])
def test_refused_keys(pendulum, key, words):
    with pytest.raises(ModelError) as info:
        pendulum.simulate(**RUN, sensitivities=[key])
    assert words in str(info.value) and key in str(info.value)


@pytest.mark.parametrize("options, words", [
    (dict(method="baumgarte"), "rk4 or dopri5 method"),
    (dict(project=False), "projected rk4"),
    (dict(sensitivities=[]), "at least one parameter"),
    (dict(sensitivities=["gravity[1]", "gravity[1]"]), "named twice"),
])
def test_refused_runs(pendulum, options, words):
    run = {**RUN, "sensitivities": ["gravity[1]"], **options}
    with pytest.raises(ValueError, match=words.replace("[", r"\[")):
        pendulum.simulate(**run)


def test_result_sensitivity_and_its_errors(pendulum, with_sens):
    s = with_sens.sensitivity("P2.x", "bodies.rod1.mass")
    assert s.shape == with_sens.t.shape and s[0] == 0.0 and np.any(s)
    assert with_sens.info["sensitivities"] == ["bodies.rod1.mass", "gravity[1]"]
    with pytest.raises(KeyError, match="run's parameters are: bodies.rod1.mass"):
        with_sens.sensitivity("P2.x", "bodies.rod2.mass")
    with pytest.raises(KeyError, match="has no sensitivity"):
        with_sens.sensitivity("constraint_error", "gravity[1]")
    with pytest.raises(KeyError, match="no column 'P9.x'"):
        with_sens.sensitivity("P9.x", "gravity[1]")
    with pytest.raises(KeyError, match="has no sensitivities"):
        pendulum.simulate(**RUN).sensitivity("P2.x", "gravity[1]")


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_files_keep_the_sensitivities(with_sens, tmp_path, suffix):
    back = Result.load(with_sens.save(tmp_path / f"r{suffix}"))
    for col in ("P2.x", "energy", "rod2.wz"):
        assert np.array_equal(back.sensitivity(col, "gravity[1]"),
                              with_sens.sensitivity(col, "gravity[1]"))


def test_cli_writes_the_sensitivity_columns(build_dir, tmp_path, capsys):
    out = tmp_path / "S.csv"
    code = main(["sensitivity", str(EXAMPLES / "double_pendulum.yaml"), "--params",
                 "bodies.rod1.mass,gravity[1]", "--t-end", "0.05", "--build-dir",
                 str(build_dir), "--out", str(out), "-q"])
    assert code == 0
    table = Result.load(out)
    assert "d(P2.x)/d(bodies.rod1.mass)" in table.names
    assert all(n == "t" or n.startswith("d(") for n in table.names)
    assert "d(bodies.rod1.mass)" in capsys.readouterr().out
    code = main(["sensitivity", str(EXAMPLES / "double_pendulum.yaml"), "--params",
                 "bodies.rod9.mass", "--build-dir", str(build_dir), "-q"])
    assert code == 2 and "no body named 'rod9'" in capsys.readouterr().err



def test_the_energy_of_a_spring_wound_past_half_a_turn_has_its_derivative(
        build_dir, tmp_path):
    """An arm spun at 6 rad/s against a weak torsion spring (0.5 N m/rad, 0.3 rad
    wound at the start) winds it to about 5 rad. The energy is conserved, so its
    derivative with respect to the stiffness is that of the start's k phi0^2 / 2:
    phi0^2 / 2 = 0.045 J per N m/rad at every record. Before, the energy's chain rule
    read the spring within half a turn of its planned reference: -1.9 at 3.8 rad and
    12.7 at the end. 1e-9: RK4 at 1 ms keeps this energy to about 1e-10 J, and the
    chain rule's Richardson differences are good to about 1e-12 relative."""
    from test_angle_turns import SPUN
    path = tmp_path / "spun.yaml"
    path.write_text(SPUN)
    r = fccgen.load(path, build_dir=build_dir).simulate(
        t_end=1.5, output_dt=0.05, sensitivities=["loads[0].stiffness"], reactions=False)
    assert r["H.angle"].max() > 4.5
    d = r.sensitivity("energy", "loads[0].stiffness")
    assert np.abs(d - 0.5 * 0.3 ** 2).max() < 1e-9
