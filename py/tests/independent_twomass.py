"""Independent simulator of a two-mass spring (numpy and scipy only, no stabilis code).

A force F drives mass 1, which a spring k and a damper c couple to mass 2; a viscous friction
b2 of mass 2 against the ground is the hidden effect. Both positions are measured. The
experimenter's state feedback runs at 200 Hz on noisy positions and velocities, designed on
the documented model of data/twomass.toml, with a band-limited white excitation (0.2-20 Hz)
added to the force and a white force disturbance on mass 1, held over each sample. The plant is
discretised exactly (zero-order hold). Logs are CSV (t, F, x1, x2, r_F), one file per
experiment, as DESIGN.md describes. The lightly damped mode (3.8 Hz, 0.12 Hz half-power width
without the friction, 0.30 Hz with b2 = 0.8) is what a Welch estimate must resolve.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.linalg import expm

FS = 200.0
K = np.array([131.55136, 16.928528, -10.422267, 4.12048])  # the model file's [controller]


@dataclass(frozen=True)
class Plant:
    m1: float = 1.05                 # documented 1.0
    m2: float = 0.48                 # documented 0.5
    k: float = 190.0                 # documented 200
    c: float = 0.25                  # documented 0.2
    b2: float = 0.0                  # hidden friction of mass 2


def matrices(p: Plant) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([[0, 1, 0, 0],
                  [-p.k / p.m1, -p.c / p.m1, p.k / p.m1, p.c / p.m1],
                  [0, 0, 0, 1],
                  [p.k / p.m2, p.c / p.m2, -p.k / p.m2, -(p.c + p.b2) / p.m2]])
    b = np.array([[0.0], [1 / p.m1], [0.0], [0.0]])
    return a, b


def zoh(a: np.ndarray, b: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    n, m = b.shape
    e = expm(np.block([[a, b], [np.zeros((m, n + m))]]) * h)
    return e[:n, :n], e[:n, n:]


def campaign(directory: Path, plant: Plant = Plant(), seconds: float = 45.0,
             experiments: int = 4, seed: int = 0) -> Path:
    """Writes one CSV per experiment into `directory` and returns it."""
    directory.mkdir(parents=True, exist_ok=True)
    a, b = matrices(plant)
    ad, bd = zoh(a, b, 1.0 / FS)
    n = int(seconds * FS)
    for e in range(experiments):
        rng = np.random.default_rng(1000 * seed + e)
        spectrum = np.fft.rfft(rng.normal(size=n))
        f = np.fft.rfftfreq(n, 1.0 / FS)
        spectrum[(f < 0.2) | (f > 20.0)] = 0.0
        r = np.fft.irfft(spectrum, n)
        r /= r.std()
        w = rng.normal(0.0, 0.05, n)                       # force disturbance, N
        state_noise = rng.normal(0.0, [2e-5, 2e-3, 2e-5, 2e-3], (n, 4))
        sensor = rng.normal(0.0, 2e-5, (n, 2))
        x = np.zeros(4)
        u = np.empty(n)
        y = np.empty((n, 2))
        for i in range(n):
            y[i] = x[[0, 2]] + sensor[i]
            u[i] = -K @ (x + state_noise[i]) + r[i]
            x = ad @ x + bd[:, 0] * (u[i] + w[i])
        t = np.arange(n) / FS
        np.savetxt(directory / f"exp{e}.csv", np.column_stack([t, u, y, r]), delimiter=",",
                   header="t,F,x1,x2,r_F", comments="", fmt="%.12g")
    return directory
