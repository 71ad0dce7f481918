"""Draw the figures of docs/flexible.md from the example models and the test data
(Python API of fccgen).

    python docs/figures/make_flexible_figures.py

from the repository root (with fccgen importable); writes docs/figures/flexible_*.png,
prints the figures the page quotes, and builds the models under ./generated.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import fccgen  # noqa: E402
from fccgen.analysis import linearize, modes, statics  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
OUT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT / "tests"))
from test_cables_statics import CANTILEVER, elastica  # noqa: E402


def cantilever(tmp, n, P, EA, EI):
    path = Path(tmp) / f"c{n}.yaml"
    path.write_text(CANTILEVER.format(name="cantilever", elements=n, P=P, EA=EA, EI=EI,
                                      length=1.0))
    s = fccgen.load(path)
    q = statics(s).q
    k = s.plan.index["beam.tip"]
    return s, q, q[3 * k:3 * k + 3]


def statics_figure(tmp):
    """Tip error against the number of elements: small load (beam theory), large
    deflection (elastica); the deflected shapes of the large one."""
    ns = [2, 4, 8, 16, 32]
    small = []
    for n in ns:
        tip = cantilever(tmp, n, -0.02, 1e5, 20.0)[2]
        small.append(abs(tip[1] / (-0.02 / 60.0) - 1.0))
    ref = elastica(3.0, 1e5, 1.0)
    large, shapes = [], {}
    for n in ns[1:]:
        s, q, tip = cantilever(tmp, n, 3.0, 1e5, 1.0)
        large.append(float(np.max(np.abs(tip[:2] - ref[:2]))))
        shapes[n] = s, q
    print("small load, relative tip error:", dict(zip(ns, small)))
    print("large deflection, tip error (m):", dict(zip(ns[1:], large)))
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.6))
    a.loglog(ns, small, "o-", label="small load: |w / (P L^3/3EI) - 1|")
    a.loglog(ns[1:], large, "s-", label="large deflection: tip error (m)")
    a.axhline(1e-3, color="grey", ls=":", lw=1)
    a.axhline(1e-4, color="grey", ls="--", lw=1)
    a.set_xticks(ns, [str(n) for n in ns])
    a.minorticks_off()
    a.set_xlabel("elements")
    a.legend(fontsize=8)
    a.set_title("cantilever: convergence")
    from fccgen.viz.cables import cable_lines
    for n in (4, 16):
        s, q = shapes[n]

        class R:
            t = np.zeros(1)
            columns = {f"{name}.{c}": np.array([q[3 * k + j]])
                       for k, (name, _) in enumerate(s.plan.triples)
                       for j, c in enumerate("xyz")}
        x, y, _ = cable_lines(s.plan.model, R, 0)
        b.plot([v for v in x if v is not None], [v for v in y if v is not None],
               label=f"{n} elements")
    b.plot([ref[0]], [ref[1]], "k*", ms=10, label="elastica tip (solve_bvp)")
    b.set_aspect("equal")
    b.set_xlabel("x (m)")
    b.set_ylabel("y (m)")
    b.legend(fontsize=8)
    b.set_title("P L^2/EI = 3: tip turned 56 degrees")
    fig.tight_layout()
    fig.savefig(OUT / "flexible_cantilever.png", dpi=110)


def modes_table():
    s = fccgen.load(EXAMPLES / "cantilever.yaml")
    f = modes(linearize(s, statics(s).q)).frequency_hz
    EI, rhoA, EA = 20.0, 2.0, 1e5
    bl = np.array([1.8751, 4.6941, 7.8548])
    ref = bl ** 2 / (2 * np.pi) * np.sqrt(EI / rhoA)
    axial = np.sqrt(EA / rhoA) / 4
    print("| mode | fccgen (Hz) | closed form (Hz) | difference |")
    for k, r in enumerate(ref):
        print(f"| bending {k + 1} | {f[2 * k]:.5f} | {r:.5f} | {f[2 * k] / r - 1:.2e} |")
    a = f[np.argmin(np.abs(f - axial))]
    print(f"| axial 1 | {a:.5f} | {axial:.5f} | {a / axial - 1:.2e} |")


def pendulum_figure():
    s = fccgen.load(EXAMPLES / "flexible_pendulum.yaml")
    r = s.simulate()
    ref = np.loadtxt(ROOT / "tests" / "data" / "exudyn_flexible_pendulum.csv",
                     delimiter=",", skiprows=2)
    x = np.interp(ref[:, 0], r.t, r["rod.tip.x"])
    y = np.interp(ref[:, 0], r.t, r["rod.tip.y"])
    err = np.hypot(x - ref[:, 1], y - ref[:, 2])
    print(f"pendulum: max tip distance to Exudyn {err.max():.3g} m, energy drift "
          f"{r.info['energy_drift']:.3g} J of peak kinetic "
          f"{r.info['energy_check']['kinetic_energy_peak']:.3g} J, "
          f"{r.info['wall_time']:.2f} s for {r.info['steps']} steps")
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.4))
    a.plot(r.t, r["rod.tip.x"], label="tip x, fccgen")
    a.plot(r.t, r["rod.tip.y"], label="tip y, fccgen")
    a.plot(ref[::5, 0], ref[::5, 1], "k.", ms=3, label="Exudyn")
    a.plot(ref[::5, 0], ref[::5, 2], "k.", ms=3)
    a.set_xlabel("t (s)")
    a.set_ylabel("m")
    a.legend(fontsize=8)
    a.set_title("flexible pendulum: tip")
    b.semilogy(ref[:, 0], np.maximum(err, 1e-12))
    b.set_xlabel("t (s)")
    b.set_title("distance of the tips (m)")
    fig.tight_layout()
    fig.savefig(OUT / "flexible_pendulum.png", dpi=110)


def array_figure():
    s = fccgen.load(EXAMPLES / "solar_array_boom.yaml")
    r = s.simulate()
    latched = fccgen.load(EXAMPLES / "solar_array_boom_latched.yaml")
    m = modes(linearize(latched, statics(latched).q))
    from test_cables_array import ringing
    latch = r.events[0]["t"]
    f, zeta = ringing(r, latch + 0.2)
    print(f"array: latch at t = {latch:.4f} s; ringing {f:.5f} Hz, zeta {zeta:.5f}; "
          f"modes of the latched state {m.frequency_hz[0]:.5f} Hz, zeta "
          f"{m.damping_ratio[0]:.5f}; {r.info['wall_time']:.2f} s for "
          f"{r.info['steps']} steps")
    fig, (a, b) = plt.subplots(2, 1, figsize=(8, 4.4))
    a.plot(r.t, np.degrees(r["R.angle"]))
    a.axvline(latch, color="grey", ls=":")
    a.set_ylabel("R.angle (deg)")
    a.set_title("solar-array boom: deployment, latch, ring-down")
    b.plot(r.t, 1e3 * r["boom.tip.y"], lw=0.8)
    b.axvline(latch, color="grey", ls=":")
    b.set_xlim(latch - 0.1, r.t[-1])
    b.set_ylim(-150, 150)
    a.set_xlabel("t (s)")
    b.set_xlabel("t (s)")
    b.set_ylabel("boom.tip.y (mm)")
    fig.tight_layout()
    fig.savefig(OUT / "flexible_array.png", dpi=110)


def main():
    with tempfile.TemporaryDirectory() as tmp:
        statics_figure(tmp)
    modes_table()
    pendulum_figure()
    array_figure()


if __name__ == "__main__":
    main()
