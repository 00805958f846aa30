"""An exothermic stirred-tank reactor held at its open-loop unstable steady state: an
independent simulator (numpy, and scipy for the LQR design; no stabilis code) for the
workbench's tests.

A first-order Arrhenius reaction A -> B with a cooling jacket (Seborg's example, time in
seconds): states the concentration CA (mol/L) and the temperature T (K), input the coolant
temperature Tc (K), output the measured T. The middle steady state (T = 350 K) is unstable at
+0.047 1/s. A PI loop on T samples at 1 s and adds a periodic random-phase multisine (200
samples, lines up to 0.35 Hz) to Tc; the feed temperature and concentration drift slowly
(AR(1), about 200 s), T carries 0.05 K of sensor noise, and the plant is integrated by RK4 at
0.1 s. Each record is logged as CSV `t,Tc,T,r_Tc` in absolute units after a 600 s warm-up.

`loop=lqr` is another rig: an analyser also measures CA (0.005 mol/L of noise), an LQR on CA,
T and the integral of T's error (designed on the nominal linearization) holds the reactor,
sampled at 3 s, the multisine of 256 samples on lines up to 0.055 Hz at 2 K rms (7 periods),
white process noise drives both states instead of the feed drift, and each record is logged
as `t,Tc,T,CA,r_Tc`. Hidden effects: a 3 s thermocouple lag, a 3 s coolant
delay, or (`hidden=offset`) a thermocouple reading 0.5 K high.

    python independent_cstr.py OUTDIR SEED [hidden=lag|delay|offset|none] [clock=s|min]
        [units=K|C] [loop=pi|lqr]
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np

Q_V, CA_FEED, T_FEED = 1 / 60, 1.0, 350.0       # 1/s, mol/L, K
K0, E_R, HEAT = 7.2e10 / 60, 8750.0, 5e4 / (1000 * 0.239)
UA, VRC = 5e4 / 60, 100 * 1000 * 0.239          # J/(s K), J/K
T0, CA0, TC0 = 350.0, 0.5000170110093768, 300.0017011009377
SUBSTEPS, WARM_UP = 10, 600
KP, TI, NOISE = 3.0, 60.0, 0.05
LAG, DELAY = 3.0, 3.0                            # s: the thermocouple lag, the coolant delay
OFFSET, ANALYSER = 0.5, 0.005                    # K: the thermocouple's offset; mol/L of noise
PROCESS = np.array([3.5e-4, 0.02])               # white process noise per sample (lqr rig)


class Rig(NamedTuple):
    """Sampling and excitation: the period `ts` (s), a multisine of `period` samples on its
    first `lines` lines with `excitation` K rms, `periods` periods logged."""
    ts: float
    period: int
    lines: int
    excitation: float
    periods: int


RIGS = {"pi": Rig(1.0, 200, 70, 1.5, 8), "lqr": Rig(3.0, 256, 42, 2.0, 7)}


def rates(x: np.ndarray, tc: float, t_feed: float, ca_feed: float) -> np.ndarray:
    ca, t = x
    r = K0 * np.exp(-E_R / t) * ca
    return np.array([Q_V * (ca_feed - ca) - r, Q_V * (t_feed - t) + HEAT * r + UA / VRC * (tc - t)])


def lqr_gain(ts: float) -> np.ndarray:
    """The LQR gain on (CA, T, integral of T's error) of the nominal linearization sampled
    at `ts` with the coolant held."""
    from scipy.linalg import expm, solve_discrete_are

    x0, eps = np.array([CA0, T0]), 1e-6
    a = np.column_stack([(rates(x0 + eps * e, TC0, T_FEED, CA_FEED)
                          - rates(x0 - eps * e, TC0, T_FEED, CA_FEED)) / (2 * eps)
                         for e in np.eye(2)])
    b = (rates(x0, TC0 + eps, T_FEED, CA_FEED) - rates(x0, TC0 - eps, T_FEED, CA_FEED)) / (2 * eps)
    m = expm(np.block([[a, b[:, None]], [np.zeros((1, 3))]]) * ts)
    aa = np.block([[m[:2, :2], np.zeros((2, 1))], [np.array([[0.0, ts, 1.0]])]])
    ba = np.vstack([m[:2, 2:], [[0.0]]])
    q, r = np.diag([1 / 0.01 ** 2, 1.0, 1 / 120.0 ** 2]), np.array([[4.0]])
    p = solve_discrete_are(aa, ba, q, r)
    return np.linalg.solve(r + ba.T @ p @ ba, ba.T @ p @ aa)[0]


def record(rng: np.random.Generator, hidden: str, loop: str = "pi") -> np.ndarray:
    """One record, rows (t, Tc, T, r_Tc) in s and K (the lqr rig also logs CA after T)."""
    rig = RIGS[loop]
    lines = np.arange(1, rig.lines + 1)
    phases = rng.uniform(0, 2 * np.pi, len(lines))
    one = np.cos(2 * np.pi * np.outer(np.arange(rig.period), lines) / rig.period + phases).sum(
        axis=1)
    r = np.tile(rig.excitation * one / one.std(), rig.periods + 1)
    x, sensor, integral = np.array([CA0, T0]), T0, 0.0
    queue = [TC0] * (round(DELAY / rig.ts) if hidden == "delay" else 0)
    t_feed, ca_feed = T_FEED, CA_FEED
    h = rig.ts / SUBSTEPS
    rows = []
    gain = lqr_gain(rig.ts) if loop == "lqr" else None
    for k in range(-WARM_UP, len(r)):
        rk = r[k] if k >= 0 else 0.0
        measured = (sensor if hidden == "lag" else x[1]) + rng.normal(0, NOISE)
        measured += OFFSET if hidden == "offset" else 0.0
        error = measured - T0
        if gain is None:
            integral += error * rig.ts
            u = TC0 - KP * (error + integral / TI) + rk
            logged = (measured,)
        else:
            ca = x[0] + rng.normal(0, ANALYSER)
            u = TC0 - gain @ np.array([ca - CA0, error, integral]) + rk
            integral += error * rig.ts
            logged = (measured, ca)
        if k >= 0:
            rows.append((k * rig.ts, u, *logged, rk))
        queue.append(u)
        applied = queue.pop(0)
        if gain is None:
            t_feed = T_FEED + 0.995 * (t_feed - T_FEED) + rng.normal(0, 0.02)
            ca_feed = CA_FEED + 0.995 * (ca_feed - CA_FEED) + rng.normal(0, 5e-4)
        for _ in range(SUBSTEPS):
            k1 = rates(x, applied, t_feed, ca_feed)
            k2 = rates(x + h / 2 * k1, applied, t_feed, ca_feed)
            k3 = rates(x + h / 2 * k2, applied, t_feed, ca_feed)
            k4 = rates(x + h * k3, applied, t_feed, ca_feed)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            sensor += h * (x[1] - sensor) / LAG
        if gain is not None:
            x = x + rng.normal(0, PROCESS)
        if not (np.all(np.isfinite(x)) and abs(x[1] - T0) < 40):
            raise RuntimeError(f"the loop lost the reactor at sample {k}")
    return np.array(rows)


def campaign(out: Path, seed: int, hidden: str = "none", clock: str = "s", units: str = "K",
             records: int = 4, loop: str = "pi") -> None:
    """`records` CSV files in `out`: time in seconds or minutes, temperatures in K or C."""
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    header = "t,Tc,T,CA,r_Tc" if loop == "lqr" else "t,Tc,T,r_Tc"
    for e in range(records):
        rows = record(rng, hidden, loop)
        if clock == "min":
            rows[:, 0] /= 60
        if units == "C":
            rows[:, 1:3] -= 273.15
        np.savetxt(out / f"exp{e}.csv", rows, delimiter=",", header=header,
                   comments="", fmt="%.9g")


if __name__ == "__main__":
    options = dict(a.split("=", 1) for a in sys.argv[3:])
    campaign(Path(sys.argv[1]), int(sys.argv[2]), **options)
