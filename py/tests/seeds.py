"""Seeds of the studies on independent simulators that take a minute or more per seed. The
first seed runs on every `scripts/test.sh` (and CI); the further seeds, which give the rates the
README states, carry the `campaign` mark and run with `scripts/test.sh --campaigns`."""
from __future__ import annotations

import pytest


def campaign_seeds(*seeds) -> list:
    """`seeds` (or tuples of parameters) for `pytest.mark.parametrize`, every one after the
    first marked `campaign`."""
    first, *rest = seeds
    mark = pytest.mark.campaign
    return [first, *(pytest.param(*s, marks=mark) if isinstance(s, tuple)
                     else pytest.param(s, marks=mark) for s in rest)]


def campaign_cases(seeds: dict, *names: str) -> list:
    """(case, seed) pairs of `seeds` (each case's seeds, by name) for the cases `names` (all
    where none are named), each case's seeds after its first marked `campaign`."""
    return [p for c in (names or seeds) for p in campaign_seeds(*((c, s) for s in seeds[c]))]
