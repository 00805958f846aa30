"""Detection power before the experiment: how large an effect must be for the workbench to
find it with this excitation, this noise and this many periods, and how often it finds one that
is not there (the Python side of ``stabilis power``).

>>> result = stabilis.power("cart_pole.toml", ["logs/"], effect="cart_friction",
...                         values=[0, 0.1, 0.2, 0.5], campaigns=100)      # doctest: +SKIP
>>> result["min_detectable"]                                                 # doctest: +SKIP
{'value': 0.17, 'ci': [0.15, 0.21], ...}

Each campaign simulates the nominal model fitted to the logs plus the effect at one value, in
closed loop with the model file's ``[controller]``, driven by the logged excitation, with the
noise estimated from the logs, and runs the full discovery on it. Campaigns are pure functions
of (study, value index, campaign index, seed): in-process they run on Rust threads with the
GIL released; with ``client=`` (a ``dask.distributed.Client``) every Dask task is a batch of
campaigns and the study travels to the workers as text (model-file contents and excitation
arrays, no paths), so a remote cluster works. The outcomes are aggregated once, in Rust, so
both ways give the same result to the bit.
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

from . import _stabilis
from ._arrays import real_scalar

_native = _stabilis.power


def run_batch(spec: str, jobs, threads: int = 1) -> str:
    """Runs the campaigns ``jobs`` [(value index, campaign index), ...] of the study ``spec``
    (JSON text) without the GIL; returns their outcomes as JSON text. One Dask task."""
    return _native.run(spec, [tuple(j) for j in jobs], threads)


class _Printer:
    """Prints "power: done/total campaigns, rate/s" on stderr about twenty times per study."""

    def __init__(self):
        self.started = time.monotonic()

    def __call__(self, done: int, total: int) -> None:
        if done % max(1, total // 20) and done != total:
            return
        rate = done / max(time.monotonic() - self.started, 1e-9)
        print(f"power: {done}/{total} campaigns, {rate:.2f}/s", file=sys.stderr, flush=True)


def _progress(progress):
    if progress is True:
        return _Printer()
    if progress in (False, None):
        return lambda done, total: None
    if callable(progress):
        return progress
    raise TypeError("progress must be True, False or a callable(done, total)")


def _model_path(model) -> str:
    if isinstance(model, (str, os.PathLike)):
        return os.fspath(model)
    raise TypeError(
        "model must be the path of a model file: a power study ships the file's text to the "
        "workers (a Model built from Python callables cannot be)"
    )


def prepare(model, data, *, effect: str, values, campaigns: int = 100, seed: int = 1,
            estimator: str = "auto", criterion: str | None = None) -> str:
    """Fits the nominal model to the logs, estimates their noise; returns the study (JSON text)."""
    if isinstance(data, (str, os.PathLike)):
        data = [data]
    return _native.prepare(_model_path(model), [os.fspath(p) for p in data], effect,
                           [real_scalar(v, "values") for v in values], int(campaigns), int(seed),
                           estimator, criterion)


def run_study(spec: str, *, client=None, batch: int | None = None, threads: int | None = None,
              progress=True) -> list[str]:
    """Runs every campaign of ``spec``; returns the outcome batches (JSON texts)."""
    jobs = _native.jobs(spec)
    total = len(jobs)
    report = _progress(progress)
    batches = []
    if client is None:
        threads = threads or os.cpu_count() or 1
        size = batch or 2 * threads
        for start in range(0, total, size):
            batches.append(run_batch(spec, jobs[start:start + size], threads))
            report(min(start + size, total), total)
        return batches
    from dask.distributed import as_completed

    workers = max(1, len(client.scheduler_info().get("workers", {})))
    size = batch or max(1, min(16, total // (4 * workers)))
    chunks = [jobs[i:i + size] for i in range(0, total, size)]
    # The study is scattered once, not sent with every task.
    shared = client.scatter(spec, broadcast=True)
    futures = [client.submit(run_batch, shared, chunk, 1, pure=False) for chunk in chunks]
    done = 0
    for future in as_completed(futures):
        batches.append(future.result())
        done += len(json.loads(batches[-1]))
        report(done, total)
    return batches


def power(model, data, *, effect: str, values, campaigns: int = 100, seed: int = 1,
          client=None, batch: int | None = None, threads: int | None = None, progress=True,
          estimator: str = "auto", criterion: str | None = None, report=None) -> dict:
    """Monte-Carlo power study of the workbench for the effect ``effect`` at each of ``values``.

    ``model`` is a model file with a ``[controller]``, ``data`` the logs (paths or directories)
    whose excitation, lengths and noise the campaigns replay. Returns the result as a dict:
    ``{"effect", "campaigns", "values": [{"value", "detection_rate", "ci", "other_found_rate",
    "unexplained_rate", "estimate_mean", "estimate_std", "false_discovery_rate", ...}],
    "min_detectable": {"value", "ci"}, "failures": [...], ...}`` (the JSON of ``stabilis power``).
    ``client``: a ``dask.distributed.Client`` to run the campaigns on, ``batch`` campaigns per
    task; ``progress``: True prints on stderr, or a callable ``(done, total)``; ``report``: a
    directory for the HTML report; ``criterion``: ``"frf"`` or ``"time"`` for the nominal fit
    and every campaign's discovery (default: time for a nonlinear model file, as ``discover``).
    """
    spec = prepare(model, data, effect=effect, values=values, campaigns=campaigns, seed=seed,
                   estimator=estimator, criterion=criterion)
    batches = run_study(spec, client=client, batch=batch, threads=threads, progress=progress)
    return json.loads(_native.aggregate(spec, batches,
                                        None if report is None else os.fspath(Path(report))))
