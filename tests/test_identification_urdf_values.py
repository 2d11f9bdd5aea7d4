"""model.urdf's prior masses: the greedy over bodies run by bisection makes the same choices and the
same final call as the plain greedy, with O(log n) calls per rejected body (issue 28: TALOS 35 → 8 SDPs)."""

from __future__ import annotations

import numpy as np
import pytest

from sensorless.identification.urdf_values import greedy_prefixes


def _naive(order, reach):
    kept, cand = [], None
    for k in order:
        trial = reach(kept + [k])
        if trial is not None:
            kept, cand = kept + [k], trial
    return kept, cand


@pytest.mark.parametrize("seed", range(30))
def test_bisection_greedy_is_the_plain_greedy(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 40))
    order = list(rng.permutation(n))
    # a monotone oracle: a set of bodies is reachable iff it holds at most `cap` of the "hard" ones
    hard = set(rng.choice(n, size=int(rng.integers(0, n + 1)), replace=False).tolist()) if n else set()
    cap = int(rng.integers(0, 4))
    calls: list[tuple] = []

    def oracle(ks):
        return np.array(ks, dtype=float) if sum(k in hard for k in ks) <= cap else None

    def reach(ks):
        calls.append(tuple(ks))
        return oracle(ks)

    kept, cand = greedy_prefixes(order, reach)
    kept0, cand0 = _naive(order, oracle)
    assert kept == kept0
    assert (cand is None and cand0 is None) or np.array_equal(cand, cand0)
    # few calls, and the result comes from a call on exactly the final list (as the greedy's last success)
    rejected = len(order) - len(kept)
    assert len(calls) <= 1 + rejected * (2 * np.log2(max(n, 2)) + 3)
    if kept:
        assert tuple(kept) in calls
