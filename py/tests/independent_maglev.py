"""Independent simulator of a magnetic levitator (no stabilis code, numpy only).

A steel ball of unit mass hangs below an electromagnet: m z'' = m g - k i^2 / z^2 - c z' + w,
z the gap (m), i the coil current (A), c an eddy-current damping (hidden effect), w a force
disturbance held over each sample. The coil current follows the command through a first-order
lag `tau` (hidden effect; 0 = none). A sensor mount with a resonance `flex_hz` (hidden, no
candidate describes it) adds `q`, q'' = -wn^2 q - 2 zeta wn q' - flex_gain z''. The
experimenter's controller is a PD on the measured gap at 1 kHz (its derivative filtered),
designed on the documented model, with a white excitation added to the current command; the
ball equilibrium differs from the documented gap by the PD's steady-state offset. Logs are CSV
(t, i, z, r_i) as DESIGN.md describes, one file per experiment.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

G = 9.81
Z_DOC, I_DOC = 0.01, 1.0            # documented gap (m) and current (A) of the model file


@dataclass(frozen=True)
class Plant:
    z_eq: float = 0.0102             # gap where 1 A holds the ball (2 % off the documented one)
    c: float = 0.0                   # eddy-current damping, 1/s
    tau: float = 0.0                 # coil lag, s
    flex_hz: float = 0.0             # sensor-mount resonance, Hz (0 = none)
    flex_gain: float = 0.3


@dataclass(frozen=True)
class Config:
    plant: Plant = Plant()
    fs: float = 1000.0
    duration: float = 15.0
    experiments: int = 4
    r_rms: float = 0.03              # excitation on the current command, A
    w_rms: float = 0.02              # force disturbance, N (unit mass)
    sensor: float = 2e-6             # gap sensor noise, m
    substeps: int = 4
    seed: int = 0


def simulate(cfg: Config) -> list[np.ndarray]:
    """One (t, i, z, r_i) table per experiment."""
    p = cfg.plant
    k = G * p.z_eq**2                # k i^2 / z^2 = g at z_eq, i = 1 A
    a, b = 2 * G / Z_DOC, 2 * G / I_DOC
    kp, kd = (7200 + a) / b, 120.0 / b   # closed-loop poles near -60 +- 60j on the documented model
    h = 1.0 / cfg.fs
    hs = h / cfg.substeps
    wn = 2 * np.pi * p.flex_hz
    tables = []
    for e in range(cfg.experiments):
        rng = np.random.default_rng(cfg.seed * 100 + e)
        n = int(cfg.duration * cfg.fs)
        r = rng.normal(0.0, cfg.r_rms, n)
        w = rng.normal(0.0, cfg.w_rms, n)
        noise = rng.normal(0.0, cfg.sensor, n)
        s = np.array([Z_DOC, 0.0, I_DOC, 0.0, 0.0])   # z, v, coil current, q, q'
        prev, dz = None, 0.0
        out = np.empty((n, 4))
        for kk in range(n):
            y = s[0] + s[3] + noise[kk]
            prev = y if prev is None else prev
            dz = 0.7 * dz + 0.3 * (y - prev) / h
            prev = y
            cmd = I_DOC + kp * (y - Z_DOC) + kd * dz + r[kk]
            out[kk] = (kk * h, cmd, y, r[kk])

            def f(x):
                acc = G - k * x[2] ** 2 / x[0] ** 2 - p.c * x[1] + w[kk]
                di = (cmd - x[2]) / p.tau if p.tau > 0 else 0.0
                qdd = -wn**2 * x[3] - 2 * 0.05 * wn * x[4] - p.flex_gain * acc if wn else 0.0
                return np.array([x[1], acc, di, x[4], qdd])

            if p.tau <= 0:
                s[2] = cmd
            for _ in range(cfg.substeps):
                k1 = f(s)
                k2 = f(s + hs / 2 * k1)
                k3 = f(s + hs / 2 * k2)
                k4 = f(s + hs * k3)
                s = s + hs / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        tables.append(out)
    return tables


def campaign(directory: Path, **kw) -> list[Path]:
    """Simulates Config(**kw) into `directory` (exp_01.csv, ...)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for e, table in enumerate(simulate(Config(**kw)), start=1):
        path = directory / f"exp_{e:02d}.csv"
        np.savetxt(path, table, delimiter=",", header="t,i,z,r_i", comments="", fmt="%.12g")
        paths.append(path)
    return paths


if __name__ == "__main__":
    # python independent_maglev.py DIR [SEED] [FIELD=VALUE ...]: Plant fields, e.g. c=8
    #   tau=0.003 flex_hz=120.
    args = sys.argv[2:]
    seed = int(args.pop(0)) if args and "=" not in args[0] else 0
    hidden = {k: float(v) for k, v in (a.split("=", 1) for a in args)}
    print("\n".join(map(str, campaign(Path(sys.argv[1]), plant=replace(Plant(), **hidden),
                                       seed=seed))))
