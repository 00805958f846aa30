"""An independent simulator of a thrust-vectored hopper's pitch plane (numpy only, its own
RK4 at 1 kHz, not the workbench's code): pitch angle and rate, lateral velocity, an
aerodynamic moment that makes it unstable (doubling in 0.38 s), a discrete PID at 100 Hz on
the measured angle and rate, a periodic multisine on the gimbal command, a low-pass gust
(torque and lateral force, AR(1) of 0.3 s) and white sensor noise; cases: nominal, a 25 ms
gimbal lag, propellant slosh (a pendulum mode at 2 Hz), a 0.01 rad/s gyro bias.

Usage: python independent_hopper.py OUTDIR SEED CASE [key=value ...]
Writes OUTDIR/rec{0,1}.csv with columns t,dc,q,theta,ay,r_dc (100 Hz). Row k: u[k] (dc, held
t[k]..t[k+1]), y[k] measured at t[k]; the accelerometer sees u[k], as the README's timing says.
"""
import sys, os, json
import numpy as np

# ---- truth (the model file documents values 5-15% off these) ----
TRUTH = dict(m=40.0, g=9.81, J=12.0, lg=0.60, Mth=36.0, Cq=3.0, Mv=2.0, Dv=8.0,
             tau=0.025, ms=4.0, ws=2 * np.pi * 2.0, zs=0.05, hs=0.30, bq=0.01)
H = 0.01          # sample period
NSUB = 10         # RK4 substeps per sample (1 kHz)
PERIOD = 500      # multisine period in samples (5 s, 0.2 Hz lines)
NPER = 12         # periods per record
NREC = 2
# controller (discrete PID on theta, q): xc[k+1] = xc[k] + h*theta[k]; u = Ki*xc + Kp*theta + Kd*q + r
KP, KD, KI = 2.0, 0.42, 1.0
NOISE = dict(q=0.003, theta=0.002, ay=0.05)   # white sensor noise std
GUST_TORQUE = 1.0   # N m std, AR(1) tau 0.3 s
GUST_FORCE = 4.0    # N std, AR(1) tau 0.3 s
R_RMS = 0.012       # rad rms excitation


def deriv(x, dc, dist, p, case):
    th, q, v = x[0], x[1], x[2]
    T = p['m'] * p['g']
    if case == 'slosh':
        mr = p['m'] - p['ms']
    else:
        mr = p['m']
    if case == 'lag':
        d = x[3]
    else:
        d = dc
    Fs = 0.0
    if case == 'slosh':
        ys, ysd = x[3], x[4]
        Fs = p['ms'] * (p['ws'] ** 2 * ys + 2 * p['zs'] * p['ws'] * ysd)
    gust_M, gust_F = dist
    # lateral (inertial horizontal) force on rigid body
    Fy = T * np.sin(th + d) - p['Dv'] * v + gust_F
    if case == 'slosh':
        Fy += Fs - p['ms'] * p['g'] * np.sin(th)
    vdot = Fy / mr
    M = p['Mth'] * np.sin(th) + p['Mv'] * v - p['Cq'] * q - T * p['lg'] * np.sin(d) + gust_M
    if case == 'slosh':
        M += p['hs'] * (Fs - p['ms'] * p['g'] * np.sin(th))
    qdot = M / p['J']
    out = [q, qdot, vdot]
    if case == 'lag':
        out.append((dc - x[3]) / p['tau'])
    if case == 'slosh':
        ysdd = -Fs / p['ms'] + p['g'] * np.sin(th) - vdot - p['hs'] * qdot
        out += [x[4], ysdd]
    return np.array(out)


def accel(x, dc, dist, p, case):
    """body-lateral specific force on the rigid body (accelerometer at CG)"""
    th, q, v = x[0], x[1], x[2]
    T = p['m'] * p['g']
    mr = p['m'] - p['ms'] if case == 'slosh' else p['m']
    d = x[3] if case == 'lag' else dc
    F = T * np.sin(d) - p['Dv'] * v + dist[1]
    if case == 'slosh':
        Fs = p['ms'] * (p['ws'] ** 2 * x[3] + 2 * p['zs'] * p['ws'] * x[4])
        F += Fs
    return F / mr


def multisine(rng, n, rms):
    k = np.arange(1, n // 2)
    f = k / (n * H)
    sel = (f >= 0.2) & (f <= 15.0)
    X = np.zeros(n // 2 + 1, complex)
    ph = rng.uniform(0, 2 * np.pi, sel.sum())
    X[1:n // 2][sel] = np.exp(1j * ph)
    r = np.fft.irfft(X, n)
    return r / np.std(r) * rms


def run(outdir, seed, case, over=None):
    """Writes the records of one campaign to `outdir` and returns `outdir`."""
    over = over or {}
    p = dict(TRUTH)
    p.update({k: float(v) for k, v in over.items() if k in TRUTH})
    g = globals()
    for k, v in over.items():
        if k in ('NPER', 'NREC'):
            g[k] = int(v)
        elif k in ('R_RMS', 'GUST_TORQUE', 'GUST_FORCE'):
            g[k] = float(v)
    os.makedirs(outdir, exist_ok=True)
    rng = np.random.default_rng(seed)
    nx = 3 + (1 if case == 'lag' else 0) + (2 if case == 'slosh' else 0)
    a = np.exp(-H / NSUB / 0.3)
    for rec in range(NREC):
        r1 = multisine(rng, PERIOD, R_RMS)
        N = PERIOD * NPER
        r = np.tile(r1, NPER)
        x = np.zeros(nx)
        xc = 0.0
        gM = rng.normal() * GUST_TORQUE
        gF = rng.normal() * GUST_FORCE
        rows = []
        dprev = 0.0
        for k in range(N):
            # measure at t_k (theta, q have no feed-through)
            qm = x[1] + NOISE['q'] * rng.normal() + (p['bq'] if case == 'bias' else 0.0)
            thm = x[0] + NOISE['theta'] * rng.normal()
            u = KI * xc + KP * thm + KD * qm + r[k]
            xc = xc + H * thm
            # accelerometer at t_k sees u[k] (applied at t_k)
            aym = accel(x, u, (gM, gF), p, case) + NOISE['ay'] * rng.normal()
            rows.append((k * H, u, qm, thm, aym, r[k]))
            hs = H / NSUB
            for _ in range(NSUB):
                dist = (gM, gF)
                k1 = deriv(x, u, dist, p, case)
                k2 = deriv(x + hs / 2 * k1, u, dist, p, case)
                k3 = deriv(x + hs / 2 * k2, u, dist, p, case)
                k4 = deriv(x + hs * k3, u, dist, p, case)
                x = x + hs / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
                s = np.sqrt(1 - a * a)
                gM = a * gM + s * GUST_TORQUE * rng.normal()
                gF = a * gF + s * GUST_FORCE * rng.normal()
            if not np.all(np.isfinite(x)) or abs(x[0]) > 1.0:
                raise RuntimeError(f"the simulated loop diverged at sample {k}")
        arr = np.array(rows)
        np.savetxt(os.path.join(outdir, f"rec{rec}.csv"), arr, delimiter=',',
                   header='t,dc,q,theta,ay,r_dc', comments='', fmt='%.10g')
    with open(os.path.join(outdir, 'truth.json'), 'w') as f:
        json.dump(dict(case=case, seed=seed, params=p), f, indent=1)
    return outdir


if __name__ == '__main__':
    outdir, seed, case = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    over = dict(kv.split('=') for kv in sys.argv[4:])
    run(outdir, seed, case, over)
