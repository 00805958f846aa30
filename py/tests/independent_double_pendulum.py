"""Independent simulator of a double inverted pendulum on a cart (numpy/scipy only).

States q = (x, th1, th2) (absolute link angles from upright), qd = (xd, w1, w2).
Cart mass M; link i: mass mi, COM at li from its lower joint, inertia Ji about COM,
link 1 full length L1 (joint 2 sits at its tip).

Mass matrix:
  [M+m1+m2,      a1 c1,       a2 c2     ]
  [a1 c1,        I1,          a12 c12   ]
  [a2 c2,        a12 c12,     I2        ]
a1 = m1 l1 + m2 L1, a2 = m2 l2, a12 = m2 L1 l2, I1 = J1 + m1 l1^2 + m2 L1^2, I2 = J2 + m2 l2^2
RHS: Qx = Fc + a1 s1 w1^2 + a2 s2 w2^2
     Q1 = a1 g s1 - a12 s12 w2^2 + T1
     Q2 = a2 g s2 + a12 s12 w1^2 + T2
Joint 1 torque (cart-link1): -b1 w1 on th1. Joint 2 torque tau = -b2 (w2 - w1): +tau on th2, -tau on th1.

The links' encoders count 4096 per revolution and the cart's 0.1 mm: the quantization the
workbench names (README, "Coarsely quantized outputs"); `--no-quantization` leaves the
readings continuous (the controller is designed for the encoders either way).

Usage: python independent_double_pendulum.py OUTDIR SEED [CASE] [--no-quantization]
CASE: a nothing hidden, b joint-2 viscous friction 0.02 N m s, c cart dry friction 0.3 N,
d actuator lag 15 ms, e input delay 10 ms, f th1 encoder offset 0.01 rad.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.linalg import expm, solve_discrete_are

G = 9.81
FS = 200.0
TS = 1.0 / FS
DOC = dict(M=1.0, m1=0.3, m2=0.2, L1=0.5, l1=0.25, l2=0.25, J1=0.00625, J2=0.004)
TRUTH_SCALE = dict(M=1.04, m1=1.02, m2=0.98, L1=1.03, l1=0.97, l2=1.04, J1=0.95, J2=1.05)
TRUE = {k: v * TRUTH_SCALE[k] for k, v in DOC.items()}

N_REC = 4
T_REC = 40.0
PERIOD = 2000  # 10 s -> 0.1 Hz line spacing
LINES = np.arange(1, 101)  # 0.1 .. 10 Hz
R_RMS = 1.0  # N
SUBSTEPS = 8
X_Q = 1e-4  # m, the cart's encoder count
TH_Q = 2 * np.pi / 4096  # rad, a link encoder's count
X_NOISE = 2e-5
TH_NOISE = 2e-4
W_F = 0.05  # N, force disturbance std (held per sample)
W_T = 0.003  # N m, torque disturbance std on each link


def combos(p):
    a1 = p["m1"] * p["l1"] + p["m2"] * p["L1"]
    a2 = p["m2"] * p["l2"]
    a12 = p["m2"] * p["L1"] * p["l2"]
    I1 = p["J1"] + p["m1"] * p["l1"] ** 2 + p["m2"] * p["L1"] ** 2
    I2 = p["J2"] + p["m2"] * p["l2"] ** 2
    M0 = p["M"] + p["m1"] + p["m2"]
    return M0, a1, a2, a12, I1, I2


def accel(p, s, Fc, T1, T2, b1=0.0, b2=0.0):
    """s: (n, 6) batch of states; returns (n, 3) accelerations."""
    M0, a1, a2, a12, I1, I2 = combos(p)
    x, th1, th2, xd, w1, w2 = s.T
    c1, s1, c2, s2 = np.cos(th1), np.sin(th1), np.cos(th2), np.sin(th2)
    c12, s12 = np.cos(th1 - th2), np.sin(th1 - th2)
    n = s.shape[0]
    Mm = np.empty((n, 3, 3))
    Mm[:, 0, 0] = M0
    Mm[:, 0, 1] = Mm[:, 1, 0] = a1 * c1
    Mm[:, 0, 2] = Mm[:, 2, 0] = a2 * c2
    Mm[:, 1, 1] = I1
    Mm[:, 1, 2] = Mm[:, 2, 1] = a12 * c12
    Mm[:, 2, 2] = I2
    tau2 = -b2 * (w2 - w1)
    Q = np.stack([
        Fc + a1 * s1 * w1 ** 2 + a2 * s2 * w2 ** 2,
        a1 * G * s1 - a12 * s12 * w2 ** 2 + T1 - b1 * w1 - tau2,
        a2 * G * s2 + a12 * s12 * w1 ** 2 + T2 + tau2,
    ], axis=1)
    return np.linalg.solve(Mm, Q[:, :, None])[:, :, 0]


def linearize(p):
    """Continuous (A, B) at upright, no friction, by central differences of accel."""
    A = np.zeros((6, 6)); B = np.zeros((6, 1))
    A[0:3, 3:6] = np.eye(3)
    h = 1e-6
    for j in range(6):
        e = np.zeros((1, 6)); e[0, j] = h
        A[3:, j] = (accel(p, e, 0.0, 0.0, 0.0) - accel(p, -e, 0.0, 0.0, 0.0))[0] / (2 * h)
    B[3:, 0] = (accel(p, np.zeros((1, 6)), h, 0.0, 0.0) - accel(p, np.zeros((1, 6)), -h, 0.0, 0.0))[0] / (2 * h)
    return A, B


def c2d(A, B, T):
    n, m = B.shape
    Mx = np.zeros((n + m, n + m)); Mx[:n, :n] = A; Mx[:n, n:] = B
    E = expm(Mx * T)
    return E[:n, :n], E[:n, n:]


def design_controller():
    """Discrete LQR on a current Kalman estimate, designed on the documented linearization.
    Returns (Ac, Bc, Cc, Dc): xc[k+1] = Ac xc + Bc y, u = Cc xc + Dc y (+ r)."""
    A, B = linearize(DOC)
    Ad, Bd = c2d(A, B, TS)
    C = np.zeros((3, 6)); C[0, 0] = C[1, 1] = C[2, 2] = 1.0
    Q = np.diag([10.0, 50.0, 50.0, 1.0, 1.0, 1.0]); R = np.array([[0.1]])
    P = solve_discrete_are(Ad, Bd, Q, R)
    K = np.linalg.solve(R + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
    # Kalman filter (process noise on the accelerations, sensor noise incl. quantisation)
    Wn = np.diag([1e-8, 1e-8, 1e-8, 1e-3, 1e-1, 1e-1])
    # The design assumes the encoders whether or not a campaign quantizes.
    Vn = np.diag([X_Q ** 2 / 12 + X_NOISE ** 2, TH_Q ** 2 / 12 + TH_NOISE ** 2, TH_Q ** 2 / 12 + TH_NOISE ** 2])
    Pf = solve_discrete_are(Ad.T, C.T, Wn, Vn)
    L = Pf @ C.T @ np.linalg.inv(C @ Pf @ C.T + Vn)  # current-estimator gain
    I = np.eye(6)
    Acl = Ad - Bd @ K
    Ac = Acl @ (I - L @ C)
    Bc = Acl @ L
    Cc = -K @ (I - L @ C)
    Dc = -K @ L
    return Ac, Bc, Cc, Dc, K, Ad, Bd


CASES = {
    "a": {},
    "b": {"b2": 0.02},
    "c": {"coulomb": 0.3, "coulomb_v": 0.005},
    "d": {"tau": 0.015},
    "e": {"delay_samples": 2},  # 10 ms at 200 Hz
    "f": {"offset_th1": 0.01},
}


def multisine(rng, n):
    k = np.arange(n)
    ph = rng.uniform(0, 2 * np.pi, LINES.size)
    r = np.zeros(n)
    for li, phi in zip(LINES, ph):
        r += np.cos(2 * np.pi * li * k / PERIOD + phi)
    return r * R_RMS / np.sqrt(LINES.size / 2)


def simulate(seed, case, quantized=True):
    cfg = CASES[case]
    x_q, th_q = (X_Q, TH_Q) if quantized else (1e-12, 1e-12)
    b1 = cfg.get("b1", 0.0); b2 = cfg.get("b2", 0.0)
    fcoul = cfg.get("coulomb", 0.0); vcoul = cfg.get("coulomb_v", 0.01)
    tau = cfg.get("tau", 0.0); nd = cfg.get("delay_samples", 0)
    off1 = cfg.get("offset_th1", 0.0)
    rng = np.random.default_rng(seed)
    Ac, Bc, Cc, Dc, *_ = design_controller()
    n = int(round(T_REC * FS))
    nb = N_REC
    r = np.stack([multisine(rng, n) for _ in range(nb)])  # (nb, n)
    s = np.zeros((nb, 6))
    s[:, 1:3] = rng.normal(0, 0.002, (nb, 2))
    fa = np.zeros(nb)  # lag state (actual force)
    xc = np.zeros((nb, 6))
    ubuf = [np.zeros(nb) for _ in range(nd)]
    F_log = np.zeros((nb, n)); Y = np.zeros((nb, n, 3))
    h = TS / SUBSTEPS

    def deriv(s, fa, ucmd, wF, wT1, wT2):
        Fact = fa if tau > 0 else ucmd
        Fc = Fact + wF
        if fcoul > 0:
            Fc = Fc - fcoul * np.tanh(s[:, 3] / vcoul)
        acc = accel(TRUE, s, Fc, wT1, wT2, b1, b2)
        ds = np.concatenate([s[:, 3:6], acc], axis=1)
        dfa = (ucmd - fa) / tau if tau > 0 else np.zeros_like(fa)
        return ds, dfa

    for k in range(n):
        # measurement
        y = np.empty((nb, 3))
        y[:, 0] = np.round((s[:, 0] + rng.normal(0, X_NOISE, nb)) / x_q) * x_q
        y[:, 1] = np.round((s[:, 1] + off1 + rng.normal(0, TH_NOISE, nb)) / th_q) * th_q
        y[:, 2] = np.round((s[:, 2] + rng.normal(0, TH_NOISE, nb)) / th_q) * th_q
        u = (xc @ Cc.T + y @ Dc.T)[:, 0] + r[:, k]
        xc = xc @ Ac.T + y @ Bc.T
        F_log[:, k] = u; Y[:, k] = y
        if nd > 0:
            ubuf.append(u); uapp = ubuf.pop(0)
        else:
            uapp = u
        wF = rng.normal(0, W_F, nb); wT1 = rng.normal(0, W_T, nb); wT2 = rng.normal(0, W_T, nb)
        for _ in range(SUBSTEPS):
            k1, l1 = deriv(s, fa, uapp, wF, wT1, wT2)
            k2, l2 = deriv(s + h / 2 * k1, fa + h / 2 * l1, uapp, wF, wT1, wT2)
            k3, l3 = deriv(s + h / 2 * k2, fa + h / 2 * l2, uapp, wF, wT1, wT2)
            k4, l4 = deriv(s + h * k3, fa + h * l3, uapp, wF, wT1, wT2)
            s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            fa = fa + h / 6 * (l1 + 2 * l2 + 2 * l3 + l4)
        if not np.all(np.isfinite(s)) or np.any(np.abs(s[:, 1:3]) > 1.0):
            raise RuntimeError(f"diverged at sample {k}")
    t = np.arange(n) * TS
    return t, F_log, Y, r


def campaign(out, seed, case="a", quantized=True):
    """Writes the campaign's records as CSV files exp0.csv ... into `out`; returns `out`."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t, F, Y, r = simulate(seed, case, quantized)
    for e in range(F.shape[0]):
        data = np.column_stack([t, F[e], Y[e, :, 0], Y[e, :, 1], Y[e, :, 2], r[e]])
        np.savetxt(out / f"exp{e}.csv", data, delimiter=",", header="t,F,x,th1,th2,r_F", comments="", fmt="%.10g")
    return out


def main():
    args = [a for a in sys.argv[1:] if a != "--no-quantization"]
    seed, case = int(args[1]), (args[2] if len(args) > 2 else "a")
    campaign(args[0], seed, case, quantized="--no-quantization" not in sys.argv)


if __name__ == "__main__":
    main()
