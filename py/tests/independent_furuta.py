"""A Furuta pendulum (rotary inverted pendulum) balanced upright: an independent simulator
(numpy and scipy only, no stabilis code) for the workbench's tests.

The arm angle theta is driven by a DC motor through its voltage u (armature resistance Rm,
torque constant km, back-EMF), the pendulum angle alpha is measured from upright; the full
nonlinear Lagrangian equations (Quanser-like parameters) are integrated by RK4 on 10 sub-steps
per 2 ms sample. A discrete LQR designed on the nominal linearization acts on the measured
angles and their filtered differences (40 Hz), plus a periodic random-phase multisine on u
(4 s period, every line of 0.25-25 Hz) of `amplitude` V rms; an arm torque disturbance of
2e-4 N m is held per sample, the angles carry 2e-4 rad of white noise. Each record is logged
as CSV `t,u,theta,alpha,r_u`. `alpha_filter` puts a first-order filter (s) on the pendulum
angle's sensor.

    python independent_furuta.py OUTDIR SEED [amplitude=1.5] [alpha_filter=0]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.linalg import expm, solve_discrete_are

PARAMS = dict(Mr=0.095, Lr=0.085, mp=0.024, Lp=0.129, Rm=8.4, km=0.042, Dr=5e-5, Dp=5e-6,
              g=9.81, Jhub=0.6e-5)
FS, SUBSTEPS, PERIOD = 500.0, 10, 2000
T = 1.0 / FS
DISTURBANCE, NOISE, DERIVATIVE_HZ = 2e-4, 2e-4, 40.0


def derived(p: dict) -> dict:
    q = dict(p)
    q["Jr"] = p["Mr"] * p["Lr"] ** 2 / 3 + p["Jhub"]
    q["l"] = p["Lp"] / 2
    q["Jp0"] = p["mp"] * p["Lp"] ** 2 / 3
    return q


def accelerations(th_d: float, al: float, al_d: float, tau: float, q: dict):
    s, c = np.sin(al), np.cos(al)
    m11 = q["Jr"] + q["mp"] * q["Lr"] ** 2 + q["Jp0"] * s * s
    m12 = q["mp"] * q["Lr"] * q["l"] * c
    m22 = q["Jp0"]
    f1 = (tau - q["Dr"] * th_d - 2 * q["Jp0"] * s * c * al_d * th_d
          + q["mp"] * q["Lr"] * q["l"] * s * al_d ** 2)
    f2 = q["Jp0"] * s * c * th_d ** 2 + q["mp"] * q["g"] * q["l"] * s - q["Dp"] * al_d
    det = m11 * m22 - m12 * m12
    return (m22 * f1 - m12 * f2) / det, (m11 * f2 - m12 * f1) / det


def rates(x: np.ndarray, u: float, w: float, q: dict, alpha_filter: float) -> np.ndarray:
    """x = (theta, alpha, theta', alpha', the filtered alpha)."""
    _, al, thd, ald, af = x
    tau = q["km"] * (u - q["km"] * thd) / q["Rm"] + w
    tdd, add = accelerations(thd, al, ald, tau, q)
    daf = (al - af) / alpha_filter if alpha_filter > 0 else 0.0
    return np.array([thd, ald, tdd, add, daf])


def lqr_gain(q: dict) -> np.ndarray:
    """The discrete LQR on the nominal linearization (central differences), sampled exactly."""
    def f(x, u):
        tdd, add = accelerations(x[2], x[1], x[3], q["km"] * (u - q["km"] * x[2]) / q["Rm"], q)
        return np.array([x[2], x[3], tdd, add])
    a, b, h = np.zeros((4, 4)), np.zeros((4, 1)), 1e-7
    for j in range(4):
        e = np.zeros(4)
        e[j] = h
        a[:, j] = (f(e, 0.0) - f(-e, 0.0)) / (2 * h)
    b[:, 0] = (f(np.zeros(4), h) - f(np.zeros(4), -h)) / (2 * h)
    m = np.zeros((5, 5))
    m[:4, :4], m[:4, 4:] = a, b
    e = expm(m * T)
    ad, bd = e[:4, :4], e[:4, 4:]
    qw, r = np.diag([5.0, 20.0, 0.05, 0.05]), np.array([[1.0]])
    p = solve_discrete_are(ad, bd, qw, r)
    return np.linalg.solve(r + bd.T @ p @ bd, bd.T @ p @ ad)


def record(rng: np.random.Generator, samples: int, amplitude: float,
           alpha_filter: float) -> np.ndarray:
    """One record, rows (t, u, theta, alpha, r_u)."""
    q = derived(PARAMS)
    k = lqr_gain(q)
    lines = np.arange(1, 101)
    phases = rng.uniform(0, 2 * np.pi, lines.size)
    one = np.cos(2 * np.pi * np.outer(np.arange(PERIOD), lines) / PERIOD + phases).sum(axis=1)
    r = np.tile(one * amplitude / one.std(), samples // PERIOD + 1)[:samples]
    x = np.zeros(5)
    x[1] = x[4] = 0.01 * rng.standard_normal()
    smooth = np.exp(-2 * np.pi * DERIVATIVE_HZ * T)
    rate, previous = np.zeros(2), None
    log = np.zeros((samples, 5))
    for i in range(samples):
        y = np.array([x[0], x[4] if alpha_filter > 0 else x[1]]) + NOISE * rng.standard_normal(2)
        previous = y.copy() if previous is None else previous
        rate = smooth * rate + (1 - smooth) * (y - previous) / T
        previous = y.copy()
        u = float(-(k @ np.concatenate([y, rate]))[0] + r[i])
        log[i] = [i * T, u, y[0], y[1], r[i]]
        w, h = DISTURBANCE * rng.standard_normal(), T / SUBSTEPS
        for _ in range(SUBSTEPS):
            k1 = rates(x, u, w, q, alpha_filter)
            k2 = rates(x + h / 2 * k1, u, w, q, alpha_filter)
            k3 = rates(x + h / 2 * k2, u, w, q, alpha_filter)
            k4 = rates(x + h * k3, u, w, q, alpha_filter)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if not (np.all(np.isfinite(x)) and abs(x[1]) < 0.5):
            raise RuntimeError(f"the pendulum fell at sample {i}")
    return log


def campaign(out: Path, seed: int, amplitude: float = 1.5, alpha_filter: float = 0.0,
             records: int = 3, periods: int = 3) -> None:
    """`records` records of `periods` excitation periods each, CSV files in `out`."""
    out.mkdir(parents=True, exist_ok=True)
    for e in range(records):
        rng = np.random.default_rng(1000 * seed + e)
        log = record(rng, periods * PERIOD, amplitude, alpha_filter)
        np.savetxt(out / f"record{e}.csv", log, delimiter=",", header="t,u,theta,alpha,r_u",
                   comments="", fmt="%.9g")


if __name__ == "__main__":
    campaign(Path(sys.argv[1]), int(sys.argv[2]),
             float(sys.argv[3]) if len(sys.argv) > 3 else 1.5,
             float(sys.argv[4]) if len(sys.argv) > 4 else 0.0)
