#!/usr/bin/env python3
"""An independent simulator of an aircraft's pitch axis with relaxed static stability (one
unstable real pole) in closed loop, numpy only: angle of attack and pitch rate, elevator in,
pitch rate and normal acceleration out (the elevator feeds through to it), a low-pass gust,
RK4 on sub-steps, a digital controller at 100 Hz that computes each input from the previous
sample's measurements, a random-phase multisine on the elevator.

usage: independent_pitch.py OUTDIR SEED CASE [key=value ...]
CASE: nominal | lag | delay | madot | bending | bias
Writes OUTDIR/rec<i>.csv with columns t,de,q,nz,r_de (100 Hz) and OUTDIR/truth.json.
"""
import sys, os, json
import numpy as np
import scipy.linalg as sl

TRUTH = dict(Za=-1.2, Ma=10.0, Mq=-1.5, Md=-12.0, Zd=-0.15, V=150.0)
CFG = dict(fs=100.0, sub=10, period=1000, periods=9, records=4,
           fmin_line=1, fmax_line=200, r_rms_deg=1.0,
           q_noise=0.003, nz_noise=0.10,        # rad/s, m/s^2 (1 sigma, white)
           gust_rms=0.003, gust_wc=1.5,          # rad (alpha_g), rad/s corner
           kq=0.4, kn=0.02, ki=0.03,             # controller gains
           tau=0.030, delay=0.020, Madot=-0.6,
           bend_f=8.0, bend_z=0.03, bend_kb=60.0, bend_phi=0.01,
           q_bias=0.01, conv="same")

def plant(case, c):
    """continuous-time augmented plant: state derivative f(x, ucmd_or_surface, ag)."""
    p = TRUTH
    Za, Ma, Mq, Md, Zd, V = p["Za"], p["Ma"], p["Mq"], p["Md"], p["Zd"], p["V"]
    n = 2 + (1 if case == "lag" else 0) + (2 if case == "bending" else 0)
    wb = 2*np.pi*c["bend_f"]
    def f(x, d_in, ag):
        # d_in: the input arriving at the plant (command, delayed in 'delay' case)
        dx = np.zeros(n)
        a, q = x[0], x[1]
        dsurf = x[2] if case == "lag" else d_in
        ad = Za*(a+ag) + q + Zd*dsurf
        qd = Ma*(a+ag) + Mq*q + Md*dsurf
        if case == "madot":
            qd += c["Madot"]*ad
        dx[0], dx[1] = ad, qd
        if case == "lag":
            dx[2] = (d_in - x[2])/c["tau"]
        if case == "bending":
            eta, etad = x[2], x[3]
            dx[2] = etad
            dx[3] = -2*c["bend_z"]*wb*etad - wb**2*eta + c["bend_kb"]*dsurf
        return dx
    def meas(x, d_in, ag):
        a, q = x[0], x[1]
        dsurf = x[2] if case == "lag" else d_in
        nz = V*(Za*(a+ag) + Zd*dsurf)
        qm = q
        if case == "bending":
            qm = q + c["bend_phi"]*x[3]
        if case == "bias":
            qm = qm + c["q_bias"]
        return qm, nz
    return n, f, meas

def multisine(rng, c):
    P = c["period"]; k = np.arange(c["fmin_line"], c["fmax_line"]+1)
    ph = rng.uniform(0, 2*np.pi, k.size)
    t = np.arange(P)
    r = np.sum(np.cos(2*np.pi*np.outer(t, k)/P + ph), axis=1)
    r *= np.deg2rad(c["r_rms_deg"])/np.sqrt(np.mean(r**2))
    return r

def run_record(case, c, rng):
    fs, sub = c["fs"], c["sub"]; T = 1/fs; h = T/sub
    n, f, meas = plant(case, c)
    r1 = multisine(rng, c); N = c["period"]*c["periods"]; r = np.tile(r1, c["periods"])
    x = np.zeros(n); xi = 0.0
    # gust AR(1) at the sub-step rate
    phi_g = np.exp(-c["gust_wc"]*h); sg = c["gust_rms"]*np.sqrt(1-phi_g**2)
    ag = rng.normal()*c["gust_rms"]
    dsteps = int(round(c["delay"]/h)) if case == "delay" else 0
    buf = [0.0]*dsteps                # commanded values at sub-step resolution (delay line)
    d_applied = 0.0                   # input at the plant during the last sub-step
    y_prev = (0.0, 0.0)
    out = np.zeros((N, 5))
    for k in range(N):
        if c["conv"] == "prev":
            # sample y at t_k (sees the surface held up to t_k), then compute and apply u[k]
            qm, nzm = meas(x, d_applied, ag)
            qm += rng.normal()*c["q_noise"]; nzm += rng.normal()*c["nz_noise"]
            u = c["kq"]*qm - c["kn"]*nzm - c["ki"]*xi + r[k]
            xi += T*nzm
        else:
            # "same": u[k] computed from y[k-1] during the previous interval, applied at t_k,
            # then y[k] sampled after the switch (sees u[k] through the feed-through)
            u = c["kq"]*y_prev[0] - c["kn"]*y_prev[1] - c["ki"]*xi + r[k]
            xi += T*y_prev[1]
            d_now = u if not dsteps else (buf[0] if buf else u)
            qm, nzm = meas(x, d_now, ag)
            qm += rng.normal()*c["q_noise"]; nzm += rng.normal()*c["nz_noise"]
            y_prev = (qm, nzm)
        out[k] = [k*T, u, qm, nzm, r[k]]
        for s in range(sub):
            if dsteps:
                buf.append(u); d_in = buf.pop(0)
            else:
                d_in = u
            d_applied = d_in
            k1 = f(x, d_in, ag); k2 = f(x+h/2*k1, d_in, ag); k3 = f(x+h/2*k2, d_in, ag); k4 = f(x+h*k3, d_in, ag)
            x = x + h/6*(k1+2*k2+2*k3+k4)
            ag = phi_g*ag + sg*rng.normal()
        if not np.all(np.isfinite(x)) or abs(x[0]) > 1.0:
            raise SystemExit(f"diverged at sample {k}")
    return out

def campaign(outdir, seed, case, **changes):
    """Simulates one campaign into `outdir` (records of the CSV format above); returns it."""
    c = dict(CFG)
    c.update(changes)
    os.makedirs(outdir, exist_ok=True)
    rng = np.random.default_rng(seed*1000 + ["nominal","lag","delay","madot","bending","bias"].index(case))
    for i in range(c["records"]):
        out = run_record(case, c, rng)
        np.savetxt(os.path.join(outdir, f"rec{i}.csv"), out, delimiter=",", header="t,de,q,nz,r_de", comments="", fmt="%.9g")
    with open(os.path.join(outdir, "truth.json"), "w") as fh:
        json.dump(dict(case=case, seed=seed, truth=TRUTH, cfg=c), fh, indent=1)
    return outdir

def main():
    outdir, seed, case = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    changes = {}
    for kv in sys.argv[4:]:
        k, v = kv.split("=", 1)
        changes[k] = type(CFG[k])(v) if not isinstance(CFG[k], str) else v
    campaign(outdir, seed, case, **changes)
    d = np.loadtxt(os.path.join(outdir, "rec0.csv"), delimiter=",", skiprows=1)
    print(f"{outdir}: rms de={np.std(d[:,1]):.4f} rad q={np.std(d[:,2]):.4f} rad/s nz={np.std(d[:,3]):.3f} m/s2 r={np.std(d[:,4]):.4f}; mean q={np.mean(d[:,2]):.4f}")

if __name__ == "__main__":
    main()
