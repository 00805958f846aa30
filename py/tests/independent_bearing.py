"""An independent simulator of a rotor in a radial magnetic bearing (numpy/scipy only, no
stabilis code): two axes, each an unstable mass (x'' = k x + g i, k = 100 1/s^2) under a
decentralized PD loop at 200 Hz, with the spin coupling the axes' velocities (x'' += c y',
y'' -= c x') when `coupling` c is given. Each coil current carries an independent periodic
multisine (lines 0.5-40 Hz, 400-sample period, 6 periods after one of transient); process
noise on the currents and white sensor noise. CSV logs `t, ix, iy, xs, ys, r_ix, r_iy`.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.linalg import expm

K, G = 100.0, 1.0  # the truth: negative stiffness and current gain, per unit mass
FS, PERIOD, PERIODS, LINES = 200.0, 400, 6, 80
KP, KD = 300.0, 20.0  # the experimenter's PD gains on the measured position and the velocity


def campaign(directory: Path, seed: int, coupling: float = 0.0, experiments: int = 2,
             coil_lag: float = 0.0, sensor_lag: float = 0.0) -> Path:
    """Simulates `experiments` records into `directory` (exp_0.csv, ...). `coil_lag` (s): the
    y coil's current reaches the rotor through a first-order lag (a slower amplifier);
    `sensor_lag` (s): the y position sensor reads through one (its filter)."""
    rng = np.random.default_rng(seed)
    a = np.array([[0, 1, 0, 0], [K, 0, 0, coupling], [0, 0, 0, 1], [0, -coupling, K, 0]], float)
    b = np.array([[0, 0], [G, 0], [0, 0], [0, G]], float)
    a, b, sensed = with_lags(a, b, coil_lag, sensor_lag)
    n_x = a.shape[0]
    big = expm(np.block([[a, b], [np.zeros((2, n_x + 2))]]) / FS)  # zero-order hold
    phi, gam = big[:n_x, :n_x], big[:n_x, n_x:]
    n = PERIOD * (PERIODS + 1)
    t = np.arange(n) / FS
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    for e in range(experiments):
        r = np.zeros((n, 2))
        for j in range(2):
            phases = rng.uniform(0, 2 * np.pi, LINES)
            r[:, j] = 0.05 * sum(np.sin(2 * np.pi * (line + 1) * FS / PERIOD * t + phases[line])
                                 for line in range(LINES))
        x = np.zeros(n_x)
        u, y = np.zeros((n, 2)), np.zeros((n, 2))
        for i in range(n):
            y[i] = x[sensed] + 1e-4 * rng.standard_normal(2)
            u[i] = -(KP * y[i] + KD * x[[1, 3]]) + r[i]
            x = phi @ x + gam @ (u[i] + 0.05 * rng.standard_normal(2))
        np.savetxt(directory / f"exp_{e}.csv", np.column_stack([t, u, y, r]), delimiter=",",
                   header="t,ix,iy,xs,ys,r_ix,r_iy", comments="", fmt="%.10g")
    return directory


def with_lags(a: np.ndarray, b: np.ndarray, coil_lag: float,
              sensor_lag: float) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The rotor with a lag state for the y coil and one for the y sensor (each when its time
    constant is positive), and the states the two sensors read."""
    sensed = [0, 2]
    if coil_lag > 0:  # state l: l' = (iy - l)/tau drives vy in place of iy
        a = np.pad(a, ((0, 1), (0, 1)))
        a[3, -1], a[-1, -1] = b[3, 1], -1.0 / coil_lag
        b = np.vstack([b, [0.0, 1.0 / coil_lag]])
        b[3, 1] = 0.0
    if sensor_lag > 0:  # state s: s' = (y - s)/tau, read in place of y
        a = np.pad(a, ((0, 1), (0, 1)))
        a[-1, 2], a[-1, -1] = 1.0 / sensor_lag, -1.0 / sensor_lag
        b = np.vstack([b, [0.0, 0.0]])
        sensed = [0, a.shape[0] - 1]
    return a, b, sensed


if __name__ == "__main__":
    # python independent_bearing.py DIR SEED [COUPLING]
    campaign(Path(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]) if len(sys.argv) > 3 else 0.0)
