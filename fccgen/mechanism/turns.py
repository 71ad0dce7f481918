"""Angles over turns along records (docs/elements.md, "Angles over turns"): the rule
that the joint angle columns and the after-run forces (fccgen.numeric.record_loads)
share.

An angle measured at a record is known only within half a turn. Along records
(t_k, angle within half a turn, rate r_k) each increment is taken on the branch
nearest to the advance of the earlier rate, r_k (t_k+1 - t_k), and checked against
the trapezoid of the two rates, (r_k + r_k+1) (t_k+1 - t_k) / 2: the two estimates
differ by half the change of the rate over the interval, so where the counted
increment is more than a quarter turn from the trapezoid, the rate changed too much
between the records to place the angle on a turn, and the records from there on are
not counted. Across an event (an impact or a lock breaks the rates) the increment is
taken on the nearest branch, numpy.unwrap's rule, and not checked. Records a rotor
crosses at constant speed are counted over any number of turns between them.
"""
from __future__ import annotations

import math

import numpy as np

TURN = 2.0 * math.pi


def count_turns(raw, rate, t, impacts=(), start=None):
    """(angles, known, steps) of angles along records. raw, rate: (m, n) angles within
    half a turn and their rates at the n records t (in order of time), one row per
    angle; impacts: the event times; start: (t, angle over turns, rate) of the record
    before the first (arrays (1,), (m, 1), (m, 1)), or None: the first record starts
    the count at its raw angle. angles: (m, n) counted over turns; known: per row, the
    records counted before the first that cannot be placed on a turn (n: all); steps:
    the counted increments into each record."""
    raw, rate, t = (np.asarray(x, float) for x in (raw, rate, t))
    m, n = raw.shape
    if start is None:
        t0, a0, r0 = t[:1], raw[:, :1], rate[:, :1]
    else:
        t0, a0, r0 = (np.asarray(x, float) for x in start)
    if n == 0:
        return raw.copy(), np.zeros(m, int), np.zeros((m, 0))
    ts = np.concatenate([t0, t])
    before = np.concatenate([a0, raw], axis=1)
    rates = np.concatenate([r0, rate], axis=1)
    dt, w = np.diff(ts), np.diff(before, axis=1)
    step = w + TURN * np.round((rates[:, :-1] * dt - w) / TURN)
    impacts = np.asarray(impacts, float)
    struck = (np.searchsorted(impacts, ts[1:], side="right")
              > np.searchsorted(impacts, ts[:-1], side="right"))
    step[:, struck] = (w - TURN * np.round(w / TURN))[:, struck]
    if start is None:
        step[:, 0] = 0.0
    angles = a0 + np.cumsum(step, axis=1)
    trapezoid = 0.5 * (rates[:, :-1] + rates[:, 1:]) * dt
    far = (np.abs(step - trapezoid) > 0.25 * TURN) & ~struck
    known = np.where(far.any(axis=1), np.argmax(far, axis=1), n)
    return angles, known, step
