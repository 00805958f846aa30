"""Runs a power study's campaigns on a Dask scheduler for ``stabilis power --scheduler``:
reads the study (JSON, from ``stabilis power``) on stdin, prints the outcomes (a JSON list) on
stdout, progress on stderr.

    python -m stabilis.dask_runner --scheduler tcp://host:8786 < study.json > outcomes.json
"""
import argparse
import json
import sys

from .power_study import run_study


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m stabilis.dask_runner", description=__doc__)
    parser.add_argument("--scheduler", required=True, help="address of the Dask scheduler")
    parser.add_argument("--batch", type=int, default=None, help="campaigns per task")
    args = parser.parse_args(argv)
    from dask.distributed import Client

    spec = sys.stdin.read()
    with Client(args.scheduler) as client:
        print(f"power: on the Dask scheduler {args.scheduler}, "
              f"{len(client.scheduler_info().get('workers', {}))} workers", file=sys.stderr)
        batches = run_study(spec, client=client, batch=args.batch)
    outcomes = [o for b in batches for o in json.loads(b)]
    json.dump(outcomes, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
