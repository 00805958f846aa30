"""Nothing under ``py/src`` panics across the boundary: every public function of the package
(``pmpc`` and the workbench are tested in their own files) called with special values and
odd shapes in each argument returns or raises an ordinary exception. A Rust panic surfaces as
``pyo3_runtime.PanicException``, which derives from ``BaseException``, not ``Exception``, so
``call`` lets it through and the test fails; an abort would kill the test process."""
import inspect
import math

import numpy as np
import pytest

import stabilis
from stabilis import cubli, event_est, flying_platform, geometry, log, sim, tilt

SPECIAL = [
    math.nan,
    math.inf,
    -1.0,
    0,
    1e300,
    -(10**12),
    10**12,
    "nonsense",
    None,
    [],
    np.array([]),
    np.full(3, np.nan),
    np.full(3, 1e300),
    np.zeros((0, 3)),
    np.ones((2, 2, 2)),
    np.ones((3, 3)) * (1 + 1j),
    [[1.0, 2.0], [3.0]],
]


@pytest.fixture(autouse=True)
def in_scratch_directory(tmp_path, monkeypatch):
    """Special values given as ``out=`` are valid file names: keep what they write out of the
    source tree."""
    monkeypatch.chdir(tmp_path)


def call(f, *args, **kwargs):
    """Calls ``f``; an ordinary exception is a refusal, and fine."""
    try:
        f(*args, **kwargs)
    except Exception:  # noqa: BLE001 - any named error is acceptable here
        pass


def parameters(f):
    try:
        return list(inspect.signature(f).parameters.values())
    except (TypeError, ValueError):
        return []


def functions():
    modules = {
        "cubli": cubli,
        "event_est": event_est,
        "flying_platform": flying_platform,
        "log": log,
        "sim": sim,
        "tilt": tilt,
    }
    found = []
    for name, module in modules.items():
        for attr in module.__all__:
            obj = getattr(module, attr)
            if callable(obj) and not isinstance(obj, type):
                found.append((f"{name}.{attr}", obj))
    for space in ("so3", "s2", "matrix_set"):
        ns = getattr(geometry, space)
        for attr in sorted(vars(ns)):
            obj = getattr(ns, attr)
            if callable(obj):
                found.append((f"geometry.{space}.{attr}", obj))
    return found


# Keyword arguments that would make a valid but long computation; their bounds are checked in
# test_sizes_beyond_the_machine_are_refused instead.
SLOW = {"trials", "steps", "duration", "periods", "vehicles", "iterations", "max_iterations"}


@pytest.mark.parametrize("name,f", functions(), ids=[n for n, _ in functions()])
def test_special_values_in_each_argument_never_panic(name, f):
    params = [p for p in parameters(f) if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    n = max(len(params), 1)
    for value in SPECIAL:
        if isinstance(value, int) and abs(value) >= 10**12 and name.startswith("sim."):
            continue  # a valid duration of 1e12 s is refused by size, covered below
        # The value in every position at once, and alone in each position.
        call(f, *([value] * n))
        for p in params:
            if p.default is not inspect.Parameter.empty and p.name not in SLOW:
                call(f, **{p.name: value})


def test_classes_never_panic():
    for cls, args in [
        (cubli.Params, {}),
        (cubli.Backstepping, {}),
        (cubli.GuidingController, {}),
        (flying_platform.Model, {}),
    ]:
        for p in parameters(cls):
            for value in SPECIAL:
                call(cls, **{p.name: value})
        obj = cls(**args)
        for attr in dir(obj):
            if attr.startswith("_"):
                continue
            method = getattr(obj, attr)
            if callable(method):
                for value in SPECIAL:
                    call(method, value)
                    call(method, value, value)
    positions = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2 / np.sqrt(3)] * 3])
    est = tilt.Estimator(positions)
    for value in SPECIAL:
        call(tilt.Estimator, value)
        call(est.estimate, value)
        call(est.least_squares, value)


def test_sizes_beyond_the_machine_are_refused():
    with pytest.raises(stabilis.SimError, match="bytes"):
        cubli.simulate(duration=1e9)
    with pytest.raises(stabilis.SimError, match="bytes"):
        sim.run("wheel-pendulum", 1e12)
    with pytest.raises(stabilis.SimError, match="bytes"):
        flying_platform.simulate(duration=1e9)
    with pytest.raises(stabilis.SimError, match="bytes"):
        flying_platform.experiment_design(periods=10**9)
    with pytest.raises(stabilis.SimError, match="bytes"):
        event_est.platoon(100000)


def test_nan_excitation_is_a_value_error_not_a_panic():
    x = np.zeros((1000, 9))
    x[10, 3] = np.nan
    with pytest.raises((ValueError, stabilis.Error), match="excitation"):
        flying_platform.simulate("hover", excitation=x)


def test_complex_arrays_are_refused_not_truncated():
    with pytest.raises(TypeError, match="complex"):
        geometry.so3.exp(np.array([0.1, 0.2, 0.3]) + 1j)
    positions = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2 / np.sqrt(3)] * 3])
    est = tilt.Estimator(positions)
    with pytest.raises(TypeError, match="complex"):
        est.estimate(np.tile([0.0, 0.0, 9.81], (4, 1)) + 0.5j)
    with pytest.raises(TypeError, match="complex"):
        cubli.momenta(np.zeros(3) + 1j, np.zeros(3))
    with pytest.raises(TypeError, match="complex"):
        flying_platform.simulate(excitation=np.zeros((10, 9)) * 1j)
    # Methods of the native classes too (numpy complex scalars pass through __float__).
    g = np.array([0.0, 0.0, -9.81])
    with pytest.raises(TypeError, match="complex"):
        cubli.Backstepping().control(g + 0.1j, np.zeros(3), np.zeros(3))
    with pytest.raises(TypeError, match="complex"):
        cubli.Params(m=np.array([0.1, 0.1, 0.1]) * (1 + 1j))
    with pytest.raises(TypeError, match="complex"):
        flying_platform.Model().frequency_response(np.array([1.0, 2.0]) * (1 + 1j))
    with pytest.raises(TypeError, match="complex"):
        est.d_criterion(g * (1 + 1j))


def test_string_and_object_arrays_are_refused_not_parsed():
    # numpy.asarray(x, float64) would parse "1" as 1.0 and unpack an object array.
    with pytest.raises(TypeError, match="exp must hold real numbers; got dtype <U"):
        geometry.so3.exp(np.array(["0.1", "0.2", "0.3"]))
    with pytest.raises(TypeError, match="exp must hold real numbers; got dtype object"):
        geometry.so3.exp(np.array([0.1, 0.2, 0.3], dtype=object))
    positions = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2 / np.sqrt(3)] * 3])
    with pytest.raises(TypeError, match="positions must hold real numbers; got dtype <U"):
        tilt.Estimator(positions.astype(str))
    with pytest.raises(TypeError, match="excitation must hold real numbers; got dtype object"):
        flying_platform.simulate(excitation=np.zeros((10, 9)).astype(object))


# One number argument of each module: (call with the value, its name, a valid float and
# int or None). numpy complex scalars have __float__, which keeps the real part with only a
# ComplexWarning; a Python complex is refused even with a zero imaginary part, like arrays.
_A = np.diag(np.ones(3), 1)
_B = np.array([[0.0], [0.0], [0.0], [1.0]])
_POSITIONS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2 / np.sqrt(3)] * 3])
SCALAR_ARGUMENTS = {
    "pmpc": (lambda v: stabilis.pmpc.Controller(_A, _B, np.eye(4), np.eye(1), u_bounds=[(-0.5, 0.5)],
                                                nu=v, s=10, td=0.02), "nu", 0.7, None),
    "tilt": (lambda v: tilt.Estimator(_POSITIONS, tol=v), "tol", 1e-8, 1),
    "cubli": (lambda v: cubli.Backstepping(alpha=v), "alpha", 15.0, 15),
    "event_est": (lambda v: event_est.synthesize(event_est.platoon(2), j_max=v), "j_max", 10.0, 10),
    "flying_platform": (lambda v: flying_platform.gramian(horizon=v), "horizon", 1.0, 1),
    "geometry": (lambda v: geometry.s2.project([1.0, 2.0, 3.0], radius=v), "radius", 9.81, 2),
    "workbench": (lambda v: stabilis.Workbench(sample_rate_hz=v), "sample_rate_hz", 50.0, 50),
}


@pytest.mark.parametrize("module", list(SCALAR_ARGUMENTS))
@pytest.mark.parametrize("value", [np.complex128(1 + 1j), 1 + 0j, "0.5", np.array(0.5, dtype=object)],
                         ids=["complex128", "complex", "str", "object"])
def test_complex_string_and_object_numbers_are_refused_naming_the_argument(module, value):
    call, name, _, _ = SCALAR_ARGUMENTS[module]
    with pytest.raises(TypeError) as error:
        call(value)
    # The native functions name the argument in a note (pyo3), the wrappers in the message.
    text = " ".join([str(error.value), *getattr(error.value, "__notes__", [])])
    assert name in text
    if isinstance(value, complex):
        assert "complex" in text


@pytest.mark.parametrize("module", [m for m, case in SCALAR_ARGUMENTS.items() if case[2] is not None])
def test_real_number_arguments_still_work(module):
    call, _, real, integer = SCALAR_ARGUMENTS[module]
    call(np.float64(real))
    if integer is not None:
        call(integer)


def test_huge_rotation_vectors_and_measurements():
    # exp of a vector too large to square is still a rotation (about x by 1e300 rad).
    r = geometry.so3.exp(np.array([1e300, 0.0, 0.0]))
    a = 1e300
    np.testing.assert_allclose(
        r, [[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]], atol=1e-15
    )
    positions = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2 / np.sqrt(3)] * 3])
    est = tilt.Estimator(positions)
    with pytest.raises((ValueError, stabilis.Error), match="overflow"):
        est.estimate(np.full((4, 3), 1e300))
