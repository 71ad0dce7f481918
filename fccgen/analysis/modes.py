"""Natural frequencies, damping ratios and mode shapes of a linearized motion.

Conservative case (C_r = 0, K_r symmetric): the generalized symmetric eigenproblem
K_r phi = omega^2 M_r phi (scipy.linalg.eigh), frequency omega / (2 pi), damping 0.
Otherwise (dampers, gyroscopic or non-conservative terms): the eigenvalues s of the
state matrix A. A complex pair s = -zeta w +- i w sqrt(1 - zeta^2) is one mode with
w = |s|, zeta = -Re s / |s|; real eigenvalues are rigid motions (two zeros each) or overdamped motions, paired in order
of magnitude (the i-th smallest with the i-th largest, exact for one overdamped mode;
a convention when there are several) into w = sqrt(s1 s2),
zeta = -(s1 + s2) / (2 w).

Unstable motions: a negative frequency marks a divergent direction (omega^2 < 0 in the
eigh path, a saddle pair s1 s2 < 0 of real eigenvalues in the state-matrix path, given
as -sqrt(|s1 s2|)); a negative damping ratio a growing oscillation (flutter).

A mode whose w is at most RIGID_RTOL times the largest w (or all, when every w is
zero) is a rigid-body motion: reported with the ``rigid`` flag and frequency 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .linearize import Linearization

RIGID_RTOL = 1e-6


@dataclass
class Modes:
    """Natural frequencies (Hz), damping ratios, rigid flags and q-space shapes."""
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    rigid: np.ndarray                 # bool per mode
    shapes: np.ndarray                # (n_q, n_modes): q-space mode shapes (N phi)
    method: str                       # "eigh" or "state matrix"

    def rows(self) -> list[tuple[int, float, float, bool]]:
        return [(k + 1, float(f), float(z), bool(r)) for k, (f, z, r) in
                enumerate(zip(self.frequency_hz, self.damping_ratio, self.rigid))]

    def text(self) -> str:
        lines = [f"{len(self.frequency_hz)} modes ({self.method}); rigid: frequency below "
                 f"{RIGID_RTOL:g} x the largest"]
        lines.append(f"{'mode':>4s}  {'frequency_hz':>16s}  {'damping_ratio':>14s}")
        for k, f, z, r in self.rows():
            lines.append(f"{k:4d}  {f:16.10g}  {z:14.6g}" + ("  rigid" if r else ""))
        return "\n".join(lines)

    def write_csv(self, path, info: dict | None = None) -> None:
        """The rows ``mode, frequency_hz, damping_ratio, rigid``, written atomically,
        and how they were made (``info``: provenance, what was linearized) in the
        sidecar ``<stem>.meta.json``, as for a result (fccgen.results.files)."""
        from pathlib import Path

        from ..results.files import write_csv_with_sidecar

        def write_table(tmp):
            with open(tmp, "w", encoding="utf-8") as out:
                out.write("mode,frequency_hz,damping_ratio,rigid\n")
                for k, f, z, r in self.rows():
                    out.write(f"{k},{f:.17g},{z:.17g},{int(r)}\n")
        meta = {"fccgen_modes": 1, "rows": len(self.frequency_hz),
                "columns": ["mode", "frequency_hz", "damping_ratio", "rigid"]}
        write_csv_with_sidecar(Path(path), write_table, meta,
                               {"method": self.method, **(info or {})})


def modes(lin: Linearization) -> Modes:
    """The modes of a linearized motion (see the module docstring)."""
    K, C, M = lin.K_r, lin.C_r, lin.M_r
    N = lin.null_basis
    scale = max(np.max(np.abs(K)) if K.size else 0.0, 1e-300)
    # damping below 1e-12 of the critical scale sqrt(|K| |M|) is rounding (h and
    # dB/dt v differenced in v at v = 0), not a damper
    undamped = np.max(np.abs(C), initial=0.0) <= 1e-12 * np.sqrt(
        scale * np.max(np.abs(M), initial=0.0))
    conservative = undamped and np.max(np.abs(K - K.T), initial=0.0) <= 1e-9 * scale
    if conservative:
        w2, phi = scipy.linalg.eigh(0.5 * (K + K.T), M)
        w = np.sign(w2) * np.sqrt(np.abs(w2))        # negative: an unstable direction
        zeta = np.zeros(len(w))
        method = "eigh"
    else:
        w, zeta, phi = _from_state_matrix(lin)
        method = "state matrix"
    rigid = np.abs(w) <= RIGID_RTOL * np.max(np.abs(w), initial=0.0)
    w = np.where(rigid, 0.0, w)
    zeta = np.where(rigid, 0.0, zeta)
    return Modes(frequency_hz=w / (2.0 * np.pi), damping_ratio=zeta, rigid=rigid,
                 shapes=N @ phi, method=method)


def _from_state_matrix(lin: Linearization):
    """(w, zeta, shapes in z) from the eigenvalues of A, sorted by w."""
    n = lin.dof
    s, vec = np.linalg.eig(lin.A)
    scale = max(np.max(np.abs(s), initial=0.0), 1e-300)
    tol = 1e-9 * scale
    upper = [k for k in range(2 * n) if s[k].imag > tol]
    real = sorted((k for k in range(2 * n) if abs(s[k].imag) <= tol),
                  key=lambda k: abs(s[k]))
    out = [(abs(s[k]), -s[k].real / abs(s[k]), vec[:n, k].real) for k in upper]
    zeros = [k for k in real if abs(s[k]) <= RIGID_RTOL * scale]
    for i in range(len(zeros) // 2):            # rigid motions: s = 0 twice
        out.append((0.0, 0.0, vec[:n, zeros[2 * i]].real))
    real = real[2 * (len(zeros) // 2):]
    for i in range(len(real) // 2):
        s1, s2 = s[real[i]].real, s[real[-1 - i]].real
        w = np.sqrt(abs(s1 * s2))
        zeta = (-(s1 + s2) / (2.0 * w)) if w > 0 else 0.0
        # s1 s2 < 0: a saddle (one growing, one decaying motion), unstable: w < 0
        out.append((w if s1 * s2 >= 0.0 else -w, zeta, vec[:n, real[i]].real))
    out.sort(key=lambda m: m[0])
    w = np.array([m[0] for m in out])
    zeta = np.array([m[1] for m in out])
    phi = np.array([m[2] for m in out]).T.reshape(n, len(out))
    return w, zeta, phi
