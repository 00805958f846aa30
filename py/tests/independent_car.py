"""An independent simulator of a car's lateral dynamics (numpy only, its own RK4 at 1 kHz, not
the workbench's code): a single-track model at 30 m/s, above its critical speed of 16.7 m/s,
so the open loop is unstable (eigenvalues +2.17 and -8.27 /s, doubling in 0.32 s); a yaw-rate
loop at 100 Hz (steer = -0.6 r measured + a multisine of 0.1-5 Hz, 10 s period, 11 periods), a
low-pass wind force (AR(1) of 0.3 s, 200 N, acting 0.3 m ahead of the centre of mass) and white
sensor noise. Cases: nominal; tyrelag (each axle's force follows its steady value with the
relaxation length 0.6 m, 20 ms); roll (a roll mode at 1.5 Hz that steers the rear axle and
tilts the accelerometer); gyrobias (0.01 rad/s); nltyre (tanh tyres).

Usage: python independent_car.py OUTDIR CASE SEED
Writes OUTDIR/run<SEED>.csv with columns t,delta,r,ay,r_delta (100 Hz). Row k: the steer
delta[k] (held t[k]..t[k+1]), r[k] and ay[k] measured at t[k]; the accelerometer sees delta[k].
"""
import os
import sys

import numpy as np

TRUTH = dict(m=1500.0, Iz=2500.0, a=1.5, b=1.1, Cf=80000.0, Cr=50000.0, U=30.0,
             sigma=0.6,                      # tyre relaxation length, m (sigma / U = 20 ms)
             wroll=2 * np.pi * 1.5, zroll=0.3, groll=0.9, eroll=0.25, tilt=1.0,
             gbias=0.01,                     # gyro bias, rad/s
             Fmax_f=5600.0, Fmax_r=7500.0,   # tanh tyres (nltyre)
             g=9.81)
FS, SUB = 100.0, 10                          # sample rate, RK4 sub-steps per sample
KR = 0.6                                     # yaw-rate feedback, rad per rad/s
PERIOD_S, PERIODS, FMIN, FMAX, EXC_RMS = 10.0, 11, 0.1, 5.0, 0.01
WIND_STD, WIND_TAU, WIND_ARM = 200.0, 0.3, 0.3
NOISE_R, NOISE_AY = 0.003, 0.05


def multisine(rng):
    n = int(round(PERIOD_S * FS))
    lines = np.arange(int(np.ceil(FMIN * PERIOD_S)), int(np.floor(FMAX * PERIOD_S)) + 1)
    phases = rng.uniform(0, 2 * np.pi, len(lines))
    x = np.sum(np.cos(2 * np.pi * np.outer(lines, np.arange(n)) / n + phases[:, None]), axis=0)
    return np.tile(x * EXC_RMS / np.sqrt(np.mean(x ** 2)), PERIODS)


def deriv(case, p, x, delta, wind):
    """State derivative of [vy, r, Ff lagged, Fr lagged, phi, phi'] and the lateral
    acceleration."""
    vy, r, ffl, frl, phi, phid = x
    u = p['U']
    alf = delta - (vy + p['a'] * r) / u
    alr = -(vy - p['b'] * r) / u
    if case == 'roll':
        alr += p['eroll'] * phi
    if case == 'nltyre':
        ffs = p['Fmax_f'] * np.tanh(p['Cf'] * alf / p['Fmax_f'])
        frs = p['Fmax_r'] * np.tanh(p['Cr'] * alr / p['Fmax_r'])
    else:
        ffs, frs = p['Cf'] * alf, p['Cr'] * alr
    if case == 'tyrelag':
        ff, fr = ffl, frl
        dff, dfr = u / p['sigma'] * (ffs - ffl), u / p['sigma'] * (frs - frl)
    else:
        ff, fr, dff, dfr = ffs, frs, 0.0, 0.0
    ay = (ff + fr + wind) / p['m']
    dr = (p['a'] * ff - p['b'] * fr + wind * WIND_ARM) / p['Iz']
    if case == 'roll':
        dphi, dphid = phid, -p['wroll'] ** 2 * phi - 2 * p['zroll'] * p['wroll'] * phid + p['groll'] * ay
    else:
        dphi = dphid = 0.0
    return np.array([ay - u * r, dr, dff, dfr, dphi, dphid]), ay


def run(outdir, case, seed):
    """Writes one record of `case` to `outdir` and returns `outdir`."""
    p = TRUTH
    rng = np.random.default_rng(seed)
    exc = multisine(rng)
    h = 1.0 / (FS * SUB)
    a = np.exp(-h / WIND_TAU)
    step = WIND_STD * np.sqrt(1 - a * a)
    x, wind = np.zeros(6), rng.normal(0, WIND_STD)
    bias = p['gbias'] if case == 'gyrobias' else 0.0
    rows = np.zeros((len(exc), 5))
    for k, e in enumerate(exc):
        r_meas = x[1] + bias + NOISE_R * rng.normal()
        delta = -KR * r_meas + e
        _, ay = deriv(case, p, x, delta, wind)
        tilt = p['g'] * p['tilt'] * x[4] if case == 'roll' else 0.0
        rows[k] = [k / FS, delta, r_meas, ay + tilt + NOISE_AY * rng.normal(), e]
        for _ in range(SUB):
            k1, _ = deriv(case, p, x, delta, wind)
            k2, _ = deriv(case, p, x + h / 2 * k1, delta, wind)
            k3, _ = deriv(case, p, x + h / 2 * k2, delta, wind)
            k4, _ = deriv(case, p, x + h * k3, delta, wind)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            wind = a * wind + step * rng.normal()
        if not np.all(np.isfinite(x)) or abs(x[1]) > 5:
            raise RuntimeError(f"the simulated loop diverged at sample {k}")
    os.makedirs(outdir, exist_ok=True)
    np.savetxt(os.path.join(outdir, f"run{seed}.csv"), rows, delimiter=',',
               header='t,delta,r,ay,r_delta', comments='', fmt='%.9g')
    return outdir


if __name__ == '__main__':
    print(run(sys.argv[1], sys.argv[2], int(sys.argv[3])))
