"""Effects with states of their own: a pendulum whose angle sensor sits on a flexible mount,
simulated here (numpy, Euler on 50 sub-steps per sample, no stabilis code), described once
as a model file whose effect declares the mount's states and once as a Python model whose
`stabilis.Effect(f=, h=, states=)` does. Both routes fit the same parameters, the mount's
frequency near the truth."""
from __future__ import annotations

import math

import numpy as np
import pytest

from seeds import campaign_seeds
from test_cartpole_independent import python_model

K, C = 25.0, 12.0  # the pendulum: theta'' = K sin(theta) + C torque
MOUNT_HZ, MOUNT_ZETA, MOUNT_GAIN = 12.0, 0.03, 0.2  # q'' + 2 z w q' + w^2 q = gain theta''
FS = 100.0
AGREEMENT = 1e-4  # the Python route against the file route, every fitted parameter, relative

FILE = """
name = "pend"
states = ["theta", "omega"]
inputs = ["T"]
outputs = ["theta"]
[parameters]
k = { value = 20.0, min = 1.0, max = 100.0 }
c = { value = 10.0, min = 1.0, max = 100.0 }
[nonlinear]
f.theta = "omega"
f.omega = "k*sin(theta) + c*T"
h.theta = "theta"
operating_point = { theta = 0, omega = 0, T = 0 }
[effects.mount]
description = "flexible sensor mount"
parameters = { wm = { value = 69.0, min = 6.0, max = 300.0 }, zm = { value = 0.05, min = 0.0, max = 1.0 }, gm = { value = 0.1, min = -2.0, max = 2.0 } }
states = ["q", "qd"]
add.f.q = "qd"
add.f.qd = "gm*(k*sin(theta) + c*T) - 2*zm*wm*qd - wm^2*q"
add.h.theta = "q"
"""


def campaign(out, seed, samples=1500):
    """One record: feedback u = -5 y - 1.2 omega + r on the measured angle, r white (rms 0.6)
    held per sample, torque noise 0.02, angle noise 1e-3 rad; CSV t, T, theta, r_T."""
    rng = np.random.default_rng(seed)
    h = 1.0 / FS / 50
    wm = 2 * math.pi * MOUNT_HZ
    th = om = q = qd = 0.0
    rows = []
    for i in range(samples):
        y = th + q + 1e-3 * rng.standard_normal()
        r = 0.6 * rng.standard_normal()
        u = -5.0 * y - 1.2 * om + r
        w = 0.02 * rng.standard_normal()
        for _ in range(50):
            acc = K * math.sin(th) + C * (u + w)
            qacc = MOUNT_GAIN * acc - 2 * MOUNT_ZETA * wm * qd - wm * wm * q
            th, om, q, qd = th + h * om, om + h * acc, q + h * qd, qd + h * qacc
        rows.append((i / FS, u, y, r))
    out.mkdir(parents=True, exist_ok=True)
    np.savetxt(out / "record.csv", np.array(rows), delimiter=",", header="t,T,theta,r_T",
               comments="")
    return out


def pendulum(stabilis, **changes):
    def f(x, u, p):
        return [x[1], p["k"] * math.sin(x[0]) + p["c"] * u[0]]

    def h(x, u, p):
        return [x[0]]

    kw = dict(states=["theta", "omega"], inputs=["T"], outputs=["theta"], name="pend",
              parameters={"k": (20.0, 1.0, 100.0), "c": (10.0, 1.0, 100.0)}, f=f, h=h,
              operating_point={"theta": 0.0, "omega": 0.0, "T": 0.0})
    return stabilis.Model(**(kw | changes))


def mount_f(x, u, p):
    """x: the pendulum's theta, omega, then the mount's q, qd; returns the terms added to the
    pendulum's derivative (none) and the mount's derivative."""
    th, _, q, qd = x.tolist()
    acc = p["k"] * math.sin(th) + p["c"] * u[0]
    return [0.0, 0.0, qd, p["gm"] * acc - 2 * p["zm"] * p["wm"] * qd - p["wm"] ** 2 * q]


def mount(stabilis, **changes):
    kw = dict(f=mount_f, h=lambda x, u, p: [x[2]], states=["q", "qd"],
              bounds={"wm": (6.0, 300.0), "zm": (0.0, 1.0), "gm": (-2.0, 2.0)})
    return stabilis.Effect("mount", {"wm": 69.0, "zm": 0.05, "gm": 0.1}, **(kw | changes))


@pytest.mark.parametrize("seed", campaign_seeds(1, 2))
def test_an_effect_with_states_fits_alike_as_a_file_and_in_python(tmp_path, seed):
    stabilis = python_model()
    data = [str(campaign(tmp_path / "data", seed))]
    path = tmp_path / "pend.toml"
    path.write_text(FILE)
    by_file = stabilis.Workbench(model=stabilis.Model.from_file(str(path)), data=data)
    by_file.add("mount")
    ref = by_file.fit()["steps"][-1]
    wb = stabilis.Workbench(model=pendulum(stabilis), data=data)
    wb.add(mount(stabilis))
    got = wb.fit()["steps"][-1]
    for name, want in ref["params"].items():
        key = name if name in ("k", "c") else f"mount.{name}"
        assert got["params"][key] == pytest.approx(want, rel=AGREEMENT), (name, got, ref)
    wm, se = got["params"]["mount.wm"], got["std"]["mount.wm"]
    assert abs(wm - 2 * math.pi * MOUNT_HZ) < 3 * se, (wm, se)


def test_effect_states_are_checked_by_name(tmp_path):
    stabilis = python_model()
    with pytest.raises(ValueError, match="effect mount: states need f="):
        stabilis.Effect("mount", {"wm": 69.0}, h=lambda x, u, p: [x[2]], states=["q"])
    with pytest.raises(ValueError, match=r'operating_point names "qq", not one of its states: q, qd'):
        mount(stabilis, operating_point={"qq": 0.0})
    with pytest.raises(ValueError, match="named twice"):
        mount(stabilis, states=["q", "q"])
    data = [str(campaign(tmp_path / "data", 3, samples=300))]
    wb = stabilis.Workbench(model=pendulum(stabilis), data=data)
    short = mount(stabilis, f=lambda x, u, p: [0.0, 0.0])
    with pytest.raises(ValueError, match=r"effect mount: f\(x, u, params\) returned 2 values, expected 4"):
        wb.add(short)
