"""Simulated runs, with the same systems and defaults as ``stabilis sim <system>``.

>>> import stabilis
>>> run = stabilis.sim.run("wheel-pendulum", duration=2.0, seed=1)
>>> t, state = run["/wheel_pendulum/state"]
>>> bool(abs(state["phi"][-1]) < 0.01)
True
"""
import json

from . import _stabilis
from ._arrays import real_scalar
from .log import Log

_native = _stabilis.sim


def _arguments(duration, out, seed, options):
    args = [f"--duration={real_scalar(duration, 'duration')!r}", f"--seed={int(seed)}"]
    if out is not None:
        args.append(f"--out={out}")
    for name, value in options.items():
        flag = "--" + name.replace("_", "-")
        if value is True:
            args.append(flag)
        elif value is False or value is None:
            continue
        elif isinstance(value, (list, tuple)):
            args.append(flag + "=" + ",".join(repr(real_scalar(v, name)) for v in value))
        else:
            args.append(f"{flag}={value}")
    return args


def run(system, duration, out=None, seed=0, **options):
    """Runs ``system`` (e.g. ``"wheel-pendulum"``) for ``duration`` seconds.

    Further keyword options are the command-line options of ``stabilis sim <system>`` with
    underscores for dashes (``tilt_deg=10``, ``no_control=True``, ``noise=(0, 0, 0)``). Writes
    an MCAP log to ``out`` if given. Returns a :class:`stabilis.log.Log`
    ``{topic: (t, {field: values})}`` whose ``metadata["experiment"]`` describes the run and
    whose ``summary`` holds the headline numbers. Raises ``stabilis.SimError`` for bad options.
    """
    topics, experiment, summary, written = _native.run(
        str(system), _arguments(duration, out, seed, options)
    )
    log = Log(topics, {"experiment": experiment})
    log.summary = json.loads(summary)
    log.out = written
    return log


__all__ = ["run"]
