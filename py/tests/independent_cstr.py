"""An exothermic stirred-tank reactor held at its open-loop unstable steady state: an
independent simulator (numpy only, no stabilis code) for the workbench's tests.

A first-order Arrhenius reaction A -> B with a cooling jacket (Seborg's example, time in
seconds): states the concentration CA (mol/L) and the temperature T (K), input the coolant
temperature Tc (K), output the measured T. The middle steady state (T = 350 K) is unstable at
+0.047 1/s. A PI loop on T samples at 1 s and adds a periodic random-phase multisine (200
samples, lines up to 0.35 Hz) to Tc; the feed temperature and concentration drift slowly
(AR(1), about 200 s), T carries 0.05 K of sensor noise, and the plant is integrated by RK4 at
0.1 s. Each record is logged as CSV `t,Tc,T,r_Tc` in absolute units after a 600 s warm-up.

    python independent_cstr.py OUTDIR SEED [hidden=lag|delay|none] [clock=s|min] [units=K|C]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

Q_V, CA_FEED, T_FEED = 1 / 60, 1.0, 350.0       # 1/s, mol/L, K
K0, E_R, HEAT = 7.2e10 / 60, 8750.0, 5e4 / (1000 * 0.239)
UA, VRC = 5e4 / 60, 100 * 1000 * 0.239          # J/(s K), J/K
T0, CA0, TC0 = 350.0, 0.5000170110093768, 300.0017011009377
TS, SUBSTEPS, PERIOD, PERIODS, WARM_UP = 1.0, 10, 200, 8, 600
KP, TI, NOISE, EXCITATION = 3.0, 60.0, 0.05, 1.5
LAG, DELAY = 3.0, 3.0                            # s: the thermocouple lag, the coolant delay


def rates(x: np.ndarray, tc: float, t_feed: float, ca_feed: float) -> np.ndarray:
    ca, t = x
    r = K0 * np.exp(-E_R / t) * ca
    return np.array([Q_V * (ca_feed - ca) - r, Q_V * (t_feed - t) + HEAT * r + UA / VRC * (tc - t)])


def record(rng: np.random.Generator, hidden: str) -> np.ndarray:
    """One record, rows (t, Tc, T, r_Tc) in s and K."""
    lines = np.arange(1, int(0.35 * PERIOD) + 1)
    phases = rng.uniform(0, 2 * np.pi, len(lines))
    one = np.cos(2 * np.pi * np.outer(np.arange(PERIOD), lines) / PERIOD + phases).sum(axis=1)
    r = np.tile(EXCITATION * one / one.std(), PERIODS + 1)
    x, sensor, integral = np.array([CA0, T0]), T0, 0.0
    queue = [TC0] * (round(DELAY / TS) if hidden == "delay" else 0)
    t_feed, ca_feed = T_FEED, CA_FEED
    h = TS / SUBSTEPS
    rows = []
    for k in range(-WARM_UP, len(r)):
        rk = r[k] if k >= 0 else 0.0
        measured = (sensor if hidden == "lag" else x[1]) + rng.normal(0, NOISE)
        error = measured - T0
        integral += error * TS
        u = TC0 - KP * (error + integral / TI) + rk
        if k >= 0:
            rows.append((k * TS, u, measured, rk))
        queue.append(u)
        applied = queue.pop(0)
        t_feed = T_FEED + 0.995 * (t_feed - T_FEED) + rng.normal(0, 0.02)
        ca_feed = CA_FEED + 0.995 * (ca_feed - CA_FEED) + rng.normal(0, 5e-4)
        for _ in range(SUBSTEPS):
            k1 = rates(x, applied, t_feed, ca_feed)
            k2 = rates(x + h / 2 * k1, applied, t_feed, ca_feed)
            k3 = rates(x + h / 2 * k2, applied, t_feed, ca_feed)
            k4 = rates(x + h * k3, applied, t_feed, ca_feed)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            sensor += h * (x[1] - sensor) / LAG
        if not (np.all(np.isfinite(x)) and abs(x[1] - T0) < 40):
            raise RuntimeError(f"the loop lost the reactor at sample {k}")
    return np.array(rows)


def campaign(out: Path, seed: int, hidden: str = "none", clock: str = "s", units: str = "K",
             records: int = 4) -> None:
    """`records` CSV files in `out`: time in seconds or minutes, temperatures in K or C."""
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    for e in range(records):
        rows = record(rng, hidden)
        if clock == "min":
            rows[:, 0] /= 60
        if units == "C":
            rows[:, 1:3] -= 273.15
        np.savetxt(out / f"exp{e}.csv", rows, delimiter=",", header="t,Tc,T,r_Tc",
                   comments="", fmt="%.9g")


if __name__ == "__main__":
    options = dict(a.split("=", 1) for a in sys.argv[3:])
    campaign(Path(sys.argv[1]), int(sys.argv[2]), **options)
