"""Throughput of a power study: 200 campaigns of the issue's 4-experiment cart-pole model
(4 x 8300 samples at 100 Hz, logs of py/tests/independent_cartpole.py) on in-process threads,
against one campaign alone.

    PYTHONPATH=target/pytest-site .venv/bin/python py/bench/power_throughput.py [--threads 2]

Prints the single-campaign times (mean, median, max of --single runs, each alone), the wall
time of the 200 and the ratio of that to 200 x (one campaign) / threads. A campaign's discovery
fits its candidates on threads of its own, so one campaign alone already uses more than one
core part of the time: the ideal ratio is not exactly 1.
"""
import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import independent_cartpole as ic  # noqa: E402
from stabilis import power_study  # noqa: E402

MODEL = HERE.parent / "tests" / "data" / "cart_pole.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--campaigns", type=int, default=100, help="per value (two values)")
    parser.add_argument("--single", type=int, default=10, help="single-campaign repetitions")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        ic.campaign(Path(tmp), plant=ic.Plant(), seed=1)
        spec = power_study.prepare(MODEL, [tmp], effect="cart_friction", values=[0.0, 0.05],
                                   campaigns=args.campaigns, seed=1)
    def alone(first):
        times = []
        for c in range(first, first + args.single // 2):
            t, cpu = time.perf_counter(), time.process_time()
            power_study.run_batch(spec, [(1, c)], 1)
            times.append((time.perf_counter() - t, time.process_time() - cpu))
        return times

    load = os.getloadavg()[0]
    single = alone(0)  # half before and half after the 200, as the machine's load may change
    total = 2 * args.campaigns
    t = time.perf_counter()
    power_study.run_study(spec, threads=args.threads, progress=False)
    wall = time.perf_counter() - t
    single += alone(args.single // 2)
    cpu = statistics.mean(c for _, c in single)
    single = [w for w, _ in single]
    mean = statistics.mean(single)
    ideal = total * mean / args.threads
    print(f"cores {os.cpu_count()}, load average {load:.2f} before, {os.getloadavg()[0]:.2f} after")
    print(f"one campaign alone ({args.single} runs): mean {mean:.3f} s, median "
          f"{statistics.median(single):.3f} s, max {max(single):.3f} s; CPU {cpu:.3f} s "
          f"(its discovery's own threads)")
    print(f"{total} campaigns on {args.threads} threads: {wall:.1f} s = {wall / total:.3f} s per "
          f"campaign; {total} x one / threads = {ideal:.1f} s; ratio {wall / ideal:.2f}; "
          f"{total} x CPU of one / threads = {total * cpu / args.threads:.1f} s")


if __name__ == "__main__":
    main()
