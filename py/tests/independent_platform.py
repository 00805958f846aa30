"""An independent simulator of the flying platform's identification experiments.

Written from spec/flying_platform.md and DESIGN.md only (numpy, scipy and the official `mcap`
writer), so that the workbench is checked on data it did not produce itself. The truth is the
hover-linear model (spec §3.6) with optional momentum drag and fan gyroscopic torque (§6.7),
a fractional in-loop input delay, first-order actuator lag and a filter on the logged
velocities (§12.3); a discrete LQR of its own (designed on the nominal low-complexity model at
the sample rate, zero-order hold, the delayed input as extra states) holds hover; the 18
orthogonal random-phase multisine experiments of §6.2 (or a subset) are added to the controller
output; process and sensor noise follow §9.2 items 9-10. Logs are written as DESIGN.md
specifies: MCAP (json messages, jsonschema schemas, the `experiment` metadata) or CSV.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap.writer import Writer
from scipy.linalg import expm, solve_discrete_are
from scipy.signal import lfilter

G0 = 9.81
INPUTS = ["F1x", "F1y", "F1z", "F2x", "F2y", "F2z", "F3x", "F3y", "F3z"]
OUTPUTS = ["vx", "vy", "vz", "wx", "wy", "wz", "roll", "pitch", "yaw"]
SQ3 = math.sqrt(3.0)


@dataclass
class Vehicle:
    """Documented vehicle values (spec §7.1) and the truth's input matrix."""

    mass: float = 8.0
    l1: float = 0.1
    l3: float = 0.079
    i1: float = 0.07
    i3: float = 0.11
    hover_torque: float = 0.05
    table3_inputs: bool = True  # the identified input matrix of §7.2, else the nominal one


@dataclass
class Drag:
    """Momentum drag (spec §6.7), Table 3 values; l_alpha4 in m^2 (= 0.362 kg^-1 * I3)."""

    c_alpha1: float = 2.388
    c_alpha2: float = 4.939
    l_alpha1: float = 0.242
    l_alpha2: float = -0.138
    l_alpha3: float = -0.0084
    l_alpha4: float = 0.362 * 0.11


@dataclass
class Config:
    """One identification campaign."""

    vehicle: Vehicle = field(default_factory=Vehicle)
    drag: Drag | None = None
    c_omega_t0: float = 0.0  # fan angular momentum per fan, kg m^2/s (0: no gyroscopic torque)
    delay_s: float = 0.0  # in-loop input delay, below one sample
    actuator_tau: float = 0.0  # first-order lag of every thrust channel, s (0: none)
    velocity_log_tau: float = 0.0  # first-order filter on the logged vx, vy, vz only, s
    sample_rate_hz: float = 50.0
    period_samples: int = 250
    periods: int = 10
    transient_samples: int = 200
    lines: int = 20
    lam: tuple[float, float, float] = (1.2, 0.8, 2.0)
    experiments: tuple[int, ...] = tuple(range(1, 19))
    phase_draws: int = 200
    accel_noise: float = 0.02  # m/s^2/sqrt(Hz)
    angular_noise: float = 0.05  # rad/s^2/sqrt(Hz)
    position_sigma: float = 3e-4
    velocity_sigma: float = 0.005
    attitude_sigma: float = 0.003
    gyro_sigma: float = 0.005
    seed: int = 0


def input_matrix(v: Vehicle) -> np.ndarray:
    """B of the 12-state hover model (p, v, roll/pitch/yaw, omega) for u - u_trim (spec §6.7)."""
    t11 = np.array([[1, 0, 0, -0.5, -SQ3 / 2, 0, -0.5, SQ3 / 2, 0],
                    [0, 1, 0, SQ3 / 2, -0.5, 0, -SQ3 / 2, -0.5, 0]], float)
    if v.table3_inputs:
        t11 = np.array([[0.6966, -0.0311, 0, -0.3643, -0.7165, 0, -0.3867, 0.7286, 0],
                        [0.0330, 0.8656, 0, 0.6447, -0.3826, 0, -0.6196, -0.3775, 0]])
        bz = np.array([0, 0, 0.0967, 0, 0, 0.0896, 0, 0, 0.0670])
        v1 = np.array([[0, 0, 0.0156, 0, 0, -0.3433, 0, 0, 0.3873],
                       [0, 0, 0.4450, 0, 0, -0.2501, 0, 0, -0.2068]])
        t22_i3 = np.array([0, -0.7062, -0.1536, 0, -0.6859, -0.1030, 0, -0.7037, -0.1076])
    else:
        bz = np.array([0, 0, 1, 0, 0, 1, 0, 0, 1]) / v.mass
        v1 = np.array([[0, 0, 0, 0, 0, -SQ3 / 2, 0, 0, SQ3 / 2],
                       [0, 0, 1, 0, 0, -0.5, 0, 0, -0.5]])
        t22_i3 = -(2 * SQ3 / 3) * v.l1 * np.array([0, 1, 0, 0, 1, 0, 0, 1, 0]) / v.i3
    j2 = np.array([[0, 1], [-1, 0]], float)
    t21 = v.l3 * j2 @ t11 + (2 * SQ3 / 3) * v.l1 * v1
    b = np.zeros((12, 9))
    b[3:5] = t11 / v.mass
    b[5] = bz
    b[9:11] = t21 / v.i1
    b[11] = t22_i3
    return b


def state_matrix(v: Vehicle, drag: Drag | None, c_omega_t0: float) -> np.ndarray:
    """A of the 12-state hover model: kinematics, gravity tilt, drag and gyroscopic terms."""
    a = np.zeros((12, 12))
    a[0:3, 3:6] = np.eye(3)
    a[3, 7] = G0
    a[4, 6] = -G0
    a[6:9, 9:12] = np.eye(3)
    if drag is not None:
        c1, c2 = drag.c_alpha1, drag.c_alpha2
        a[3, 3] = a[4, 4] = -3 * c1 / v.mass
        a[5, 5] = -3 * c2 / v.mass
        a[3, 10] = -3 * drag.l_alpha1 * c1 / v.mass
        a[4, 9] = 3 * drag.l_alpha1 * c1 / v.mass
        a[9, 4] = 3 * drag.l_alpha2 * c1 / v.i1
        a[10, 3] = -3 * drag.l_alpha2 * c1 / v.i1
        a[9, 9] = a[10, 10] = -3 * drag.l_alpha3 * c1 / v.i1
        a[11, 11] = -3 * drag.l_alpha4 * c2 / v.i3
    a[9, 10] += -3 * c_omega_t0 / v.i1
    a[10, 9] += 3 * c_omega_t0 / v.i1
    return a


def plant(cfg: Config) -> tuple[np.ndarray, np.ndarray]:
    """The truth (A, B): the 12 hover states, then 9 thrust states when actuators lag."""
    a = state_matrix(cfg.vehicle, cfg.drag, cfg.c_omega_t0)
    b = input_matrix(cfg.vehicle)
    if cfg.actuator_tau <= 0.0:
        return a, b
    lag = np.eye(9) / cfg.actuator_tau
    return np.block([[a, b], [np.zeros((9, 12)), -lag]]), np.vstack([np.zeros((12, 9)), lag])


def _integral_expm(a: np.ndarray, b: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{A t}, int_0^t e^{A s} ds B) from one block exponential."""
    n, m = b.shape
    big = np.zeros((n + m, n + m))
    big[:n, :n] = a
    big[:n, n:] = b
    e = expm(big * t)
    return e[:n, :n], e[:n, n:]


def discretise(a: np.ndarray, b: np.ndarray, ts: float, delay: float):
    """x+ = Phi x + G1 u_prev + G0 u: zero-order hold with an input delay 0 <= delay < ts."""
    if not 0.0 <= delay < ts:
        raise ValueError(f"delay_s must lie in [0, {ts}), got {delay}")
    phi, _ = _integral_expm(a, b, ts)
    e_rest, g0 = _integral_expm(a, b, ts - delay)
    _, g_d = _integral_expm(a, b, delay)
    return phi, e_rest @ g_d, g0


def process_noise_cov(a: np.ndarray, q_diag: np.ndarray, ts: float) -> np.ndarray:
    """Covariance of int_0^ts e^{A s} w ds for white w with intensity diag(q) (Van Loan)."""
    n = a.shape[0]
    big = np.zeros((2 * n, 2 * n))
    big[:n, :n] = -a
    big[:n, n:] = np.diag(q_diag)
    big[n:, n:] = a.T
    e = expm(big * ts)
    phi_t = e[n:, n:]
    q = phi_t.T @ e[:n, n:]
    return 0.5 * (q + q.T)


def controller_gain(cfg: Config) -> np.ndarray:
    """Discrete LQR on the nominal low-complexity model with the delayed input as state."""
    ts = 1.0 / cfg.sample_rate_hz
    nominal = Vehicle(mass=cfg.vehicle.mass, l1=cfg.vehicle.l1, l3=cfg.vehicle.l3,
                      i1=cfg.vehicle.i1, i3=cfg.vehicle.i3, table3_inputs=False)
    phi, g1, g0 = discretise(state_matrix(nominal, None, 0.0), input_matrix(nominal), ts,
                             cfg.delay_s)
    az = np.block([[phi, g1], [np.zeros((9, 12)), np.zeros((9, 9))]])
    bz = np.vstack([g0, np.eye(9)])
    # Bryson weights (1 cm, 3 cm/s, 0.03 rad, 0.3 rad/s; 1 N): keeps the drag truth (an
    # unstable pole pair near +5 rad/s) stable with margin, also with a 15 ms delay.
    q = np.diag(np.r_[np.full(3, 1 / 0.01**2), np.full(3, 1 / 0.03**2), np.full(3, 1 / 0.03**2),
                      np.full(3, 1 / 0.3**2), np.full(9, 1e-6)])
    r = np.eye(9)
    p = solve_discrete_are(az, bz, q, r)
    return np.linalg.solve(r + bz.T @ p @ bz, bz.T @ p @ az)


def multisine(cfg: Config, rng: np.random.Generator) -> np.ndarray:
    """Line amplitudes times phases (complex, lines 1..L) of the lowest-crest-factor draw."""
    k = np.arange(1, cfg.lines + 1)
    amp = k ** -0.5
    n = np.arange(cfg.period_samples)
    best, best_crest = None, np.inf
    for _ in range(cfg.phase_draws):
        spec = amp * np.exp(1j * rng.uniform(0, 2 * np.pi, cfg.lines))
        s = periodic_signal(spec, n, cfg.period_samples)
        crest = np.abs(s).max() / np.sqrt(np.mean(s**2))
        if crest < best_crest:
            best, best_crest = spec, crest
    rms = np.sqrt(np.mean(periodic_signal(best, n, cfg.period_samples) ** 2))
    return best / rms


def periodic_signal(spec: np.ndarray, n: np.ndarray, period: int) -> np.ndarray:
    """sum_k |X_k| cos(2 pi k n / N + arg X_k) over lines k = 1..len(spec)."""
    k = np.arange(1, len(spec) + 1)
    return np.real(np.exp(2j * np.pi * np.outer(n, k) / period) @ spec)


def excitation(cfg: Config, e: int, s1: np.ndarray, s2: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Excitation of experiment e (1..18) on the nine inputs (spec §6.2), one row per sample."""
    spec = s1 if e <= 9 else s2
    k = ((e - 1) % 9) // 3
    c = (e - 1) % 3
    r = np.zeros((len(n), 9))
    for unit in range(3):
        v = np.exp(-2j * np.pi * k * unit / 3)
        r[:, 3 * unit + c] = cfg.lam[c] * periodic_signal(v * spec, n, cfg.period_samples)
    return r


def trim(v: Vehicle) -> np.ndarray:
    """Hover input (spec §3.4): weight and fan torque cancelled."""
    f2 = -v.hover_torque * SQ3 / (2 * v.l1)
    return np.tile([0.0, f2, v.mass * G0 / 3], 3)


@dataclass
class Run:
    """One experiment: logged input (trim included), excitation, measured outputs."""

    index: int
    t: np.ndarray
    u: np.ndarray
    r: np.ndarray
    y: np.ndarray  # columns OUTPUTS


def simulate(cfg: Config) -> list[Run]:
    """Closed-loop runs of the configured experiments, each a fresh hover start."""
    ts = 1.0 / cfg.sample_rate_hz
    rng = np.random.default_rng(cfg.seed)
    a, b = plant(cfg)
    nx = a.shape[0]
    phi, g1, g0 = discretise(a, b, ts, cfg.delay_s)
    # The controller sees the 12 hover states (with sensor noise) and its previous command.
    k = np.zeros((9, nx + 9))
    k_design = controller_gain(cfg)
    k[:, :12] = k_design[:, :12]
    k[:, nx:] = k_design[:, 12:]
    # Closed loop on z = (x, previous input deviation): du = -K (z + sensor noise) + r.
    a_z = np.block([[phi, g1], [np.zeros((9, nx + 9))]])
    b_z = np.vstack([g0, np.eye(9)])
    closed = a_z - b_z @ k
    radius = np.abs(np.linalg.eigvals(closed)).max()
    if radius >= 1.0:
        raise ValueError(f"the controller does not stabilise this truth (spectral radius {radius:.4f})")
    qd = process_noise_cov(a, np.r_[np.zeros(3), np.full(3, cfg.accel_noise**2), np.zeros(3),
                                    np.full(3, cfg.angular_noise**2), np.zeros(nx - 12)], ts)
    eigval, eigvec = np.linalg.eigh(qd)
    w_root = eigvec * np.sqrt(np.clip(eigval, 0.0, None))
    sigma = np.r_[np.full(3, cfg.position_sigma), np.full(3, cfg.velocity_sigma),
                  np.full(3, cfg.attitude_sigma), np.full(3, cfg.gyro_sigma)]
    s1, s2 = multisine(cfg, rng), multisine(cfg, rng)
    samples = cfg.transient_samples + cfg.periods * cfg.period_samples
    n = np.arange(samples)
    u_trim = trim(cfg.vehicle)
    measured = [3, 4, 5, 9, 10, 11, 6, 7, 8]  # state indices of OUTPUTS
    runs = []
    for e in cfg.experiments:
        r = excitation(cfg, e, s1, s2, n)
        noise = np.zeros((samples, nx + 9))
        noise[:, :12] = rng.standard_normal((samples, 12)) * sigma
        drive = (r - noise @ k.T) @ b_z.T
        drive[:, :nx] += rng.standard_normal((samples, nx)) @ w_root.T
        z = np.zeros((samples, nx + 9))  # fresh hover start
        for i in range(samples - 1):
            z[i + 1] = closed @ z[i] + drive[i]
        du = r - (z + noise) @ k.T
        y = (z[:, :12] + noise[:, :12])[:, measured]
        if cfg.velocity_log_tau > 0.0:
            pole = math.exp(-ts / cfg.velocity_log_tau)
            y[:, :3] = lfilter([1.0 - pole], [1.0, -pole], y[:, :3], axis=0)
        runs.append(Run(e, n * ts, u_trim + du, r, y))
    return runs


def sampled_frf(cfg: Config, freqs_hz: np.ndarray) -> np.ndarray:
    """The truth's exact sampled FRF (lines, 6 outputs vx..wz, 9 inputs), delay included."""
    ts = 1.0 / cfg.sample_rate_hz
    a, b = plant(cfg)
    phi, g1, g0 = discretise(a, b, ts, cfg.delay_s)
    c = np.zeros((6, a.shape[0]))
    c[range(6), [3, 4, 5, 9, 10, 11]] = 1.0
    out = []
    for f in freqs_hz:
        z = np.exp(2j * np.pi * f * ts)
        out.append(c @ np.linalg.solve(z * np.eye(a.shape[0]) - phi, g0 + g1 / z))
    return np.stack(out)


def _schema(topic: str, names: list[str]) -> bytes:
    props = {"t": {"type": "number", "description": "time, s"}}
    props.update({f: {"type": "number"} for f in names})
    return json.dumps({"title": topic, "type": "object", "properties": props,
                       "required": ["t", *names]}).encode()


def metadata(cfg: Config, run: Run) -> dict[str, str]:
    """The DESIGN.md `experiment` record: strings only."""
    c = (run.index - 1) % 3
    return {
        "sample_rate_hz": f"{cfg.sample_rate_hz:g}",
        "period_samples": str(cfg.period_samples),
        "periods": str(cfg.periods),
        "transient_samples": str(cfg.transient_samples),
        "excited": ",".join(INPUTS[3 * unit + c] for unit in range(3)),
    }


def write_mcap(path: Path, topics: dict[str, tuple[np.ndarray, list[str], np.ndarray]],
               meta: dict[str, str] | None) -> None:
    """Writes topics {name: (t, fields, values)} as json messages, log_time = t in ns."""
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="", library="stabilis independent test simulator")
        for topic, (t, names, values) in topics.items():
            schema = writer.register_schema(topic.strip("/").replace("/", "."), "jsonschema",
                                            _schema(topic, names))
            channel = writer.register_channel(topic, "json", schema)
            for ti, row in zip(t, values):
                # JSON has no NaN: a missing sample is logged as null.
                msg = {"t": float(ti),
                       **{f: float(x) if np.isfinite(x) else None for f, x in zip(names, row)}}
                ns = int(round(ti * 1e9))
                writer.add_message(channel, ns, json.dumps(msg).encode(), ns)
        if meta is not None:
            writer.add_metadata("experiment", meta)
        writer.finish()


def design_topics(system: str, inputs: list[str], outputs: list[str], run,
                  excitation_topic: bool = True):
    """The DESIGN.md topics of one run (`run` has t, u, y, r) of `system`."""
    topics = {
        f"/{system}/input": (run.t, inputs, run.u),
        f"/{system}/output": (run.t, outputs, run.y),
    }
    if excitation_topic:
        topics[f"/{system}/excitation"] = (run.t, inputs, run.r)
    return topics


def write_experiments(directory: Path, runs, topics, meta) -> list[Path]:
    """One MCAP file per run in `directory`, exp_<index>.mcap, with topics(run), meta(run)."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for run in runs:
        path = directory / f"exp_{run.index:02d}.mcap"
        write_mcap(path, topics(run), meta(run))
        paths.append(path)
    return paths


def run_topics(run: Run, excitation_topic: bool = True):
    """The DESIGN.md topics of one run."""
    return design_topics("flying_platform", INPUTS, OUTPUTS, run, excitation_topic)


def write_runs(cfg: Config, runs: list[Run], directory: Path) -> list[Path]:
    """One MCAP file per experiment in `directory`."""
    return write_experiments(directory, runs, run_topics, lambda run: metadata(cfg, run))


def write_csv(run: Run, path: Path, reverse: bool = False) -> None:
    """DESIGN.md CSV: a header row, `t` in seconds, the input and output field names (in
    reverse order, `t` last, when `reverse`: DESIGN.md fixes no column order)."""
    header = np.array(["t", *INPUTS, *OUTPUTS])
    table = np.column_stack([run.t, run.u, run.y])
    order = np.arange(len(header))[::-1] if reverse else np.arange(len(header))
    np.savetxt(path, table[:, order], delimiter=",", header=",".join(header[order]), comments="",
               fmt="%.10g")
