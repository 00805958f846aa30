"""An independent simulator of a cart-pole balanced upright in closed loop: a system stabilis
does not ship, for checking the workbench on a user's own model file (py/tests/data/cart_pole.toml).

Written with numpy/scipy and the official `mcap` writer only (no stabilis code):

* Plant (nonlinear, Lagrange): cart of mass M on a track, pole of mass m with its centre of mass
  at distance l from the pivot and inertia J about it, theta = 0 upright (unstable):

      (M + m) x'' + m l cos(theta) theta'' - m l sin(theta) theta'^2 = F_c
      m l cos(theta) x'' + (J + m l^2) theta'' - m g l sin(theta)    = T_d

  with the force on the cart F_c = F_a + w - b x' - F_coul tanh(x' / v_coul) + F_s + F_0: F_a
  the actuator force, F_0 a constant force (force_offset: a cable's pull, a driver's zero), w a
  force disturbance (process noise, held over each sample), b the cart's
  viscous friction, F_coul its dry (Coulomb) friction, smoothed over v_coul (v_coul = 0: the
  unsmoothed F_coul sign(x'), the cart chattering about rest while the force on it is below
  F_coul), and T_d a small torque disturbance on the pole.
* A flexible mode no effect of the model file and no generic effect describes (switchable): an
  appendage of mass m_f on the cart (a cable carrier, a sensor mast) on a lightly damped
  spring, q its displacement relative to the cart, natural frequency wn, damping zeta:
  F_s = m_f wn (wn q + 2 zeta q'), q'' = -x'' - F_s / m_f. Below wn it adds m_f to the cart
  (the fitted M absorbs it); around wn it puts a resonance / antiresonance pair in the band.
* Actuator chain from the logged command F to F_a, each link switchable: an exact transport
  delay td (the zero-order-hold command switches at k Ts + td, integrated as two sub-intervals)
  and a first-order lag tau F_a' = F_del - F_a.
* Integration: classical RK4 with sub-steps of at most Ts / substeps between samples.
* Sensors: x and theta at 100 Hz with white noise and a constant offset each (offset_x,
  offset_theta: a miscalibrated encoder). The controller sees the offset measurement, as on a
  rig: a theta offset makes it hold the cart away from x = 0 with the pole upright.
* Controller (its own): a discrete LQR on the current estimate of a Kalman filter, both designed
  on the nominal linearised model at the documented parameters (no friction, zero-order hold).
  The filter is driven by the measured outputs and by the controller's own output; the
  excitation r is added after the controller (as an injected actuator signal the filter does
  not see), so the controller is exactly xc[k+1] = Ac xc[k] + Bc y[k], u[k] = Cc xc[k] +
  Dc y[k] + r[k], the form of the model file's [controller] section.
* Excitation: a random-phase flat multisine on lines 1..lines of a period_samples period, a
  fresh phase draw per experiment (lowest crest factor of phase_draws draws), periods whole
  periods after transient_samples samples. FRICTION_EXCITATION: a stronger one under which the
  cart moves faster than 0.05 m/s most of the time (dry and viscous friction differ there).
* Logs: MCAP exactly per DESIGN.md (topics /cart_pole/input F, /cart_pole/output x theta,
  /cart_pole/excitation F, the `experiment` metadata) or CSV (t, F, x, theta, r_F).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.linalg import solve_discrete_are

# (e^{A t}, int_0^t e^{A s} ds B): the zero-order hold over t.
from independent_platform import _integral_expm as zoh
from independent_platform import design_topics, write_experiments

INPUTS = ["F"]
OUTPUTS = ["x", "theta"]
STATES = ["x", "xdot", "theta", "thetadot"]
SYSTEM = "cart_pole"

# The documented values (those of py/tests/data/cart_pole.toml).
DOCUMENTED = {"M": 1.0, "m": 0.2, "l": 0.3, "J": 0.006, "g": 9.81}


@dataclass
class Plant:
    """The true cart-pole and its switchable hidden effects (all off: the nominal class)."""

    M: float = 1.0 * 1.04  # cart mass, kg
    m: float = 0.2 * 1.02  # pole mass, kg
    l: float = 0.3 * 1.03  # pivot to pole centre of mass, m
    J: float = 0.006 * 0.95  # pole inertia about its centre of mass, kg m^2
    g: float = 9.81
    b: float = 0.0  # cart viscous friction, N s/m (the model file's declared effect)
    coulomb: float = 0.0  # Coulomb friction force, N
    coulomb_v: float = 0.01  # its tanh smoothing speed, m/s (0: unsmoothed, a sign)
    tau: float = 0.0  # actuator lag, s
    td: float = 0.0  # transport delay of the force, s (any value >= 0, fractional exactly)
    flex_hz: float = 0.0  # flexible appendage on the cart: natural frequency, Hz (0: none)
    flex_zeta: float = 0.05  # its damping ratio
    flex_mass: float = 0.05  # its mass, kg
    offset_x: float = 0.0  # constant offset of the cart position sensor, m
    offset_theta: float = 0.0  # constant offset of the pole angle sensor, rad
    theta_lag: float = 0.0  # first-order low-pass of the pole angle sensor, s (0: none)
    force_offset: float = 0.0  # constant force on the cart (a cable's pull, a driver's zero), N


def documented_plant() -> Plant:
    """The plant at the documented values, no effects: the model the controller is designed on."""
    return Plant(**DOCUMENTED)


@dataclass
class Config:
    """One identification campaign (default: the issue's 4 experiments x 8300 samples)."""

    plant: Plant = field(default_factory=Plant)
    sample_rate_hz: float = 100.0
    period_samples: int = 1000
    periods: int = 8
    transient_samples: int = 300
    experiments: int = 4
    lines: int = 70  # excited lines 1..lines: 0.1 .. 7 Hz at the defaults
    # Random-odd design: of lines 1..lines excite the odd ones but every fourth (k = 7 mod 8),
    # so the even lines and those odd ones are left out (detection lines for distortion).
    random_odd: bool = False
    r_rms: float = 0.3  # excitation rms, N (the pole stays within 0.05 rad of upright)
    phase_draws: int = 50
    force_noise: float = 0.05  # force disturbance per sample (held), N
    torque_noise: float = 0.002  # pole torque disturbance per sample (held), N m
    x_sigma: float = 2e-4  # cart position sensor noise, m
    theta_sigma: float = 5e-4  # pole angle sensor noise, rad
    theta0: float = 0.01  # initial pole angle, rad (the transient discards it)
    x0: float = 0.0  # initial cart position, m
    substeps: int = 4
    seed: int = 0


# Config fields of a campaign for telling dry from viscous friction (the default's 0.3 N moves
# the cart faster than 0.05 m/s a third of the time): at 1 N rms, over the 15 campaigns of
# test_nonlinear_independent.py (4 x 8300 samples; no friction, either friction, an offset),
# the cart is faster than 0.05 m/s on 72-78 % of the samples after the transient and faster
# than 0.1 m/s on 50-58 %, the pole within 0.123 rad of upright, the cart within 0.16 m of its
# start (0.27 m with a 0.01 rad angle offset, which moves its rest to -0.125 m).
FRICTION_EXCITATION = {"r_rms": 1.0}


def nominal_linear(p: Plant) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, C) of the rigid cart-pole linearised at upright, friction b included."""
    jp = p.J + p.m * p.l**2
    d = (p.M + p.m) * jp - (p.m * p.l) ** 2
    a = np.array([[0.0, 1.0, 0.0, 0.0],
                  [0.0, -p.b * jp / d, -(p.m * p.l) ** 2 * p.g / d, 0.0],
                  [0.0, 0.0, 0.0, 1.0],
                  [0.0, p.b * p.m * p.l / d, (p.M + p.m) * p.m * p.g * p.l / d, 0.0]])
    b = np.array([[0.0], [jp / d], [0.0], [-p.m * p.l / d]])
    c = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    return a, b, c


@dataclass
class Controller:
    """xc[k+1] = A xc[k] + B y[k], u[k] = C xc[k] + D y[k] + r[k]."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray


def design_controller(cfg: Config) -> Controller:
    """LQR on the current Kalman estimate, both on the documented nominal model at the rate.

    Kalman filter (current form): xf = xp + M (y - C xp); u_c = -K xf; xp+ = Ad xf + Bd u_c.
    With xc = xp this is the controller form above: A = (Ad - Bd K)(I - M C),
    B = (Ad - Bd K) M, C = -K (I - M C), D = -K M.
    """
    ts = 1.0 / cfg.sample_rate_hz
    a, b, c = nominal_linear(documented_plant())
    ad, bd = zoh(a, b, ts)
    # Bryson weights: 5 cm cart, 0.5 m/s, 0.2 rad, 0.5 rad/s; 1 N of force. Chosen (from a
    # grid) for margin: stable with a 30 ms lag plus a 15 ms delay, and with a 5 Hz, 10 %
    # damped transmission resonance, the nominal loop settling in 0.3 s.
    q = np.diag([1 / 0.05**2, 1 / 0.5**2, 1 / 0.2**2, 1 / 0.5**2])
    r = np.array([[1.0]])
    p = solve_discrete_are(ad, bd, q, r)
    k = np.linalg.solve(r + bd.T @ p @ bd, bd.T @ p @ ad)
    # The filter's noise model (fixed, whatever a campaign's noise): a 0.5 N force disturbance
    # per sample (covering the excitation it does not see), 2 mm and 5 mrad of sensor noise
    # (ten times the default sensors': a slower filter, for margin).
    qn = 0.5**2 * bd @ bd.T + 1e-10 * np.eye(4)
    rn = np.diag([2e-3**2, 5e-3**2])
    pp = solve_discrete_are(ad.T, c.T, qn, rn)  # prior covariance
    m = pp @ c.T @ np.linalg.inv(c @ pp @ c.T + rn)
    acl = ad - bd @ k
    imc = np.eye(4) - m @ c
    return Controller(A=acl @ imc, B=acl @ m, C=-k @ imc, D=-k @ m)


def controller_toml(ctrl: Controller) -> str:
    """The matrices of the model file's [controller] section (py/tests/data/cart_pole.toml
    holds those of design_controller(Config()), printed by this)."""
    def matrix(m: np.ndarray) -> str:
        rows = ["[" + ", ".join(repr(float(v)) for v in row) + "]" for row in np.atleast_2d(m)]
        return "[" + ",\n     ".join(rows) + "]"

    return "".join(f"{n} = {matrix(getattr(ctrl, n))}\n" for n in "ABCD")


# --- the nonlinear truth ------------------------------------------------------------------


def _extra_states(p: Plant) -> int:
    return (1 if p.tau > 0 else 0) + (2 if p.flex_hz > 0 else 0) + (1 if p.theta_lag > 0 else 0)


def _angle_sensed(p: Plant) -> int:
    """The state the angle sensor reads: the pole angle, or its low-pass (the last state)."""
    return 4 + _extra_states(p) - 1 if p.theta_lag > 0 else 2


def derivative(p: Plant, s: list[float], f_in: float, w: float, torque: float) -> list[float]:
    """ds/dt of the state [x, xdot, theta, thetadot, (lag force), (appendage q, q'), (sensed
    angle)]."""
    x, xd, th, thd = s[0], s[1], s[2], s[3]
    out = [xd, 0.0, thd, 0.0]
    i = 4
    f = f_in
    if p.tau > 0:
        out.append((f - s[i]) / p.tau)
        f = s[i]
        i += 1
    force = f + w - p.b * xd + p.force_offset
    if p.flex_hz > 0:  # the appendage's spring and damper pull on the cart
        wn = 2 * math.pi * p.flex_hz
        spring = p.flex_mass * wn * (wn * s[i] + 2 * p.flex_zeta * s[i + 1])
        force += spring
    if p.coulomb > 0:
        force -= p.coulomb * (math.tanh(xd / p.coulomb_v) if p.coulomb_v > 0
                              else 1.0 if xd > 0 else -1.0 if xd < 0 else 0.0)
    ml = p.m * p.l
    cth, sth = math.cos(th), math.sin(th)
    a11, a12, a22 = p.M + p.m, ml * cth, p.J + ml * p.l
    rhs1 = force + ml * sth * thd * thd
    rhs2 = ml * p.g * sth + torque
    det = a11 * a22 - a12 * a12
    out[1] = (a22 * rhs1 - a12 * rhs2) / det
    out[3] = (a11 * rhs2 - a12 * rhs1) / det
    if p.flex_hz > 0:  # q'' = -x'' - spring / m_f (q relative to the cart)
        out += [s[i + 1], -out[1] - spring / p.flex_mass]
    if p.theta_lag > 0:  # the angle sensor's low-pass, the last state
        out.append((th - s[-1]) / p.theta_lag)
    return out


def rk4(p: Plant, s: list[float], f_in: float, w: float, torque: float, h: float,
        n: int) -> list[float]:
    """n classical RK4 steps of size h with constant inputs."""
    for _ in range(n):
        k1 = derivative(p, s, f_in, w, torque)
        k2 = derivative(p, [a + 0.5 * h * b for a, b in zip(s, k1)], f_in, w, torque)
        k3 = derivative(p, [a + 0.5 * h * b for a, b in zip(s, k2)], f_in, w, torque)
        k4 = derivative(p, [a + h * b for a, b in zip(s, k3)], f_in, w, torque)
        s = [a + h / 6 * (b1 + 2 * b2 + 2 * b3 + b4)
             for a, b1, b2, b3, b4 in zip(s, k1, k2, k3, k4)]
    return s


def linearised_truth(p: Plant, eps: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the full truth (effect states included) at upright by central differences of
    `derivative` (Coulomb friction is not differentiable at rest and is left out)."""
    p = replace(p, coulomb=0.0)
    n = 4 + _extra_states(p)
    a = np.zeros((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = eps
        a[:, j] = (np.array(derivative(p, list(e), 0.0, 0.0, 0.0))
                   - np.array(derivative(p, list(-e), 0.0, 0.0, 0.0))) / (2 * eps)
    b = ((np.array(derivative(p, [0.0] * n, eps, 0.0, 0.0))
          - np.array(derivative(p, [0.0] * n, -eps, 0.0, 0.0))) / (2 * eps))[:, None]
    return a, b


def delay_split(td: float, ts: float) -> tuple[int, float]:
    """td = d Ts + phi with integer d >= 0 and 0 <= phi < Ts."""
    d = int(math.floor(td / ts + 1e-12))
    phi = td - d * ts
    if phi < 1e-12 * ts:
        phi = 0.0
    return d, phi


def linear_closed_loop(cfg: Config, ctrl: Controller) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Az, Bz, Cz) of the linearised truth (delay exact) in the loop with the controller:
    z[k+1] = Az z[k] + Bz r[k], y[k] = Cz z[k], z = (plant state, xc, u[k-1], ..., u[k-d-1])."""
    ts = 1.0 / cfg.sample_rate_hz
    a, b = linearised_truth(cfg.plant)
    n = a.shape[0]
    d, phi = delay_split(cfg.plant.td, ts)
    phi_full, _ = zoh(a, b, ts)
    e_rest, g0 = zoh(a, b, ts - phi)
    _, g_phi = zoh(a, b, phi)
    g1 = e_rest @ g_phi  # effect of u[k-d-1], held over the first phi of the interval
    c = np.zeros((2, n))
    c[0, 0] = c[1, _angle_sensed(cfg.plant)] = 1.0
    nc = ctrl.A.shape[0]
    lags = n + nc  # u[k-1] .. u[k-d-1] at lags .. lags + d
    nz = lags + d + 1
    u_row = np.zeros(nz)  # u[k] = u_row z[k] + r[k]
    u_row[:n] = (ctrl.D @ c)[0]
    u_row[n:lags] = ctrl.C[0]
    az = np.zeros((nz, nz))
    bz = np.zeros(nz)
    az[:n, :n] = phi_full
    az[:n] += g1 @ np.eye(nz)[lags + d][None, :]
    if d == 0:  # u[k] itself is held over the rest of the interval
        az[:n] += g0 @ u_row[None, :]
        bz[:n] = g0[:, 0]
    else:
        az[:n] += g0 @ np.eye(nz)[lags + d - 1][None, :]
    az[n:lags, :n] = ctrl.B @ c
    az[n:lags, n:lags] = ctrl.A
    az[lags] = u_row
    bz[lags] = 1.0
    for i in range(1, d + 1):
        az[lags + i, lags + i - 1] = 1.0
    cz = np.zeros((2, nz))
    cz[:, :n] = c
    return az, bz, cz


def sampled_frf(p: Plant, freqs_hz: np.ndarray, ts: float) -> np.ndarray:
    """The exact sampled FRF from F to (x, theta) of the linearised truth with its delay:
    (lines, 2 outputs)."""
    a, b = linearised_truth(p)
    n = a.shape[0]
    d, phi = delay_split(p.td, ts)
    phi_full, _ = zoh(a, b, ts)
    e_rest, g0 = zoh(a, b, ts - phi)
    _, g_phi = zoh(a, b, phi)
    g1 = e_rest @ g_phi
    c = np.zeros((2, n))
    c[0, 0] = c[1, _angle_sensed(p)] = 1.0
    z = np.exp(2j * np.pi * np.asarray(freqs_hz) * ts)[:, None, None]
    rhs = (g0 + g1 / z) * z ** -d
    return (c @ np.linalg.solve(z * np.eye(n) - phi_full, rhs))[:, :, 0]


def closed_loop_radius(cfg: Config, ctrl: Controller) -> float:
    """Spectral radius of the linearised truth in the loop (below 1: the loop is stable)."""
    return float(np.abs(np.linalg.eigvals(linear_closed_loop(cfg, ctrl)[0])).max())


# --- excitation and runs ------------------------------------------------------------------


def one_period(spec: np.ndarray, period: int) -> np.ndarray:
    """sum_k |X_k| cos(2 pi k n / N + arg X_k), n = 0..N-1, lines k = 1..len(spec) < N/2."""
    z = np.zeros(period // 2 + 1, complex)
    z[1:len(spec) + 1] = spec * (period / 2)
    return np.fft.irfft(z, period)


def multisine(cfg: Config, rng: np.random.Generator) -> np.ndarray:
    """One period of a flat multisine on lines 1..lines (with random_odd, the odd lines not
    7 mod 8) with the lowest-crest-factor random phases of phase_draws draws, scaled to r_rms."""
    k = np.arange(1, cfg.lines + 1)
    mask = (k % 2 == 1) & (k % 8 != 7) if cfg.random_odd else np.ones(cfg.lines, bool)
    best, best_crest = None, np.inf
    for _ in range(cfg.phase_draws):
        phases = rng.uniform(0, 2 * np.pi, cfg.lines)
        s = one_period(np.exp(1j * phases) * mask, cfg.period_samples)
        crest = np.abs(s).max() / np.sqrt(np.mean(s**2))
        if crest < best_crest:
            best, best_crest = s, crest
    return best * cfg.r_rms / np.sqrt(np.mean(best**2))


@dataclass
class Run:
    """One experiment: logged command F, excitation r, measured outputs (x, theta)."""

    index: int
    t: np.ndarray
    u: np.ndarray  # (samples, 1)
    r: np.ndarray  # (samples, 1)
    y: np.ndarray  # (samples, 2)
    state: np.ndarray  # true (x, xdot, theta, thetadot) at the samples


def samples(cfg: Config) -> int:
    return cfg.transient_samples + cfg.periods * cfg.period_samples


def simulate(cfg: Config) -> list[Run]:
    """The campaign's closed-loop experiments, each from rest at x0 with the pole at theta0."""
    ts = 1.0 / cfg.sample_rate_hz
    ctrl = design_controller(cfg)
    radius = closed_loop_radius(cfg, ctrl)
    if radius >= 1.0:
        raise ValueError(f"the controller does not stabilise this truth (radius {radius:.4f})")
    p = cfg.plant
    rng = np.random.default_rng(cfg.seed)
    count = samples(cfg)
    n = np.arange(count)
    d, phi = delay_split(p.td, ts)
    # Sub-intervals of a sample: [0, phi) holds u[k-d-1], [phi, Ts) holds u[k-d].
    parts = [(phi, -d - 1), (ts - phi, -d)] if phi > 0 else [(ts, -d)]
    steps = [(h / max(1, math.ceil(cfg.substeps * h / ts - 1e-9)),
              max(1, math.ceil(cfg.substeps * h / ts - 1e-9)), lag) for h, lag in parts]
    ac, bc, cc, dc = (np.asarray(m, float) for m in (ctrl.A, ctrl.B, ctrl.C, ctrl.D))
    offset = np.array([p.offset_x, p.offset_theta])
    sensed = _angle_sensed(p)
    runs = []
    for e in range(1, cfg.experiments + 1):
        r = multisine(cfg, rng)[n % cfg.period_samples]
        w = rng.standard_normal(count) * cfg.force_noise
        tq = rng.standard_normal(count) * cfg.torque_noise
        noise = rng.standard_normal((count, 2)) * [cfg.x_sigma, cfg.theta_sigma]
        s = [cfg.x0, 0.0, cfg.theta0, 0.0] + [0.0] * _extra_states(p)
        xc = np.zeros(ac.shape[0])
        u = np.zeros(count)
        y = np.zeros((count, 2))
        state = np.zeros((count, 4))
        for k in range(count):
            state[k] = s[:4]
            y[k] = (s[0], s[sensed])
            y[k] += noise[k]
            if offset.any():  # (skipped when zero: the default logs stay bit for bit)
                y[k] += offset
            u[k] = (cc @ xc + dc @ y[k])[0] + r[k]
            xc = ac @ xc + bc @ y[k]
            for h, m_steps, lag in steps:
                j = k + lag
                s = rk4(p, s, u[j] if j >= 0 else 0.0, w[k], tq[k], h, m_steps)
        runs.append(Run(e, n * ts, u[:, None], r[:, None], y, state))
    return runs


# --- logs ---------------------------------------------------------------------------------


def metadata(cfg: Config) -> dict[str, str]:
    """The DESIGN.md `experiment` record: strings only."""
    return {
        "sample_rate_hz": f"{cfg.sample_rate_hz:g}",
        "period_samples": str(cfg.period_samples),
        "periods": str(cfg.periods),
        "transient_samples": str(cfg.transient_samples),
        "excited": ",".join(INPUTS),
    }


def run_topics(run: Run, excitation_topic: bool = True):
    """The DESIGN.md topics of one run."""
    return design_topics(SYSTEM, INPUTS, OUTPUTS, run, excitation_topic)


def write_runs(cfg: Config, runs: list[Run], directory: Path) -> list[Path]:
    """One MCAP file per experiment in `directory` (exp_01.mcap, ...)."""
    return write_experiments(Path(directory), runs, run_topics, lambda run: metadata(cfg))


def write_csv(run: Run, path: Path) -> None:
    """CSV: a header row t, F, x, theta, r_F (the excitation of F)."""
    table = np.column_stack([run.t, run.u, run.y, run.r])
    np.savetxt(path, table, delimiter=",", header="t,F,x,theta,r_F", comments="", fmt="%.10g")


def campaign(directory: Path, **kw) -> tuple[Config, list[Path]]:
    """Simulates Config(**kw) (plant effects as Plant fields under `plant`) into directory."""
    cfg = Config(**kw)
    return cfg, write_runs(cfg, simulate(cfg), Path(directory))


if __name__ == "__main__":
    # python independent_cartpole.py DIR [SEED] [FIELD=VALUE ...]: a default campaign into DIR,
    #   the truth's hidden effects as Plant fields, e.g. b=1.2 tau=0.03 td=0.015 flex_hz=4
    #   coulomb=0.3 coulomb_v=0 offset_theta=0.01, and Config fields prefixed `cfg.`, e.g.
    #   cfg.r_rms=1.0 (FRICTION_EXCITATION);
    # python independent_cartpole.py --controller: the model file's controller matrices.
    import sys

    if sys.argv[1] == "--controller":
        print(controller_toml(design_controller(Config())), end="")
    else:
        args = sys.argv[2:]
        seed = int(args.pop(0)) if args and "=" not in args[0] else 0
        pairs = [a.split("=", 1) for a in args]
        hidden = {k: float(v) for k, v in pairs if not k.startswith("cfg.")}
        settings = {k[4:]: type(getattr(Config(), k[4:]))(float(v))
                    for k, v in pairs if k.startswith("cfg.")}
        plant = replace(Plant(), **hidden)
        print("\n".join(map(str, campaign(Path(sys.argv[1]), plant=plant, seed=seed,
                                           **settings)[1])))
