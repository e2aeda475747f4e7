#!/usr/bin/python3
"""Expected values of the optimiser comparison's statistics, computed with
SciPy and NumPy rather than the code under test, for
tests/results/optimizer_stats_test.cpp.

  /usr/bin/python3 scripts/optimizer-stats-expected.py > tests/results/optimizer_stats_expected.json

Which function gives what:
  quantiles   numpy.quantile(method="linear") and, to cross-check it,
              scipy.stats.mstats.mquantiles(alphap=1, betap=1)
  rank sums   scipy.stats.mannwhitneyu(x, y, alternative="two-sided",
              method="asymptotic", use_continuity=True): U (of x) and p;
              Vargha-Delaney A = U / (n m); z from scipy.stats.norm.isf(p / 2)
  Holm        SciPy has no Holm correction; written out here from its
              definition (Holm 1979), separately from the C++
  ERT         COCO's definition written out here: evaluations of all runs
              (to the hit for the successful ones) over the successes

Inputs are fixed (a seeded NumPy generator, rounded so that some values tie),
so the file is the same on every run.
"""

import json
import math
import sys

import numpy as np
from scipy import stats
from scipy.stats import mstats


def samples():
    rng = np.random.default_rng(20261126)
    cases = []
    # Continuous scores, as optimisers' final scores: no ties.
    cases.append(("no_ties_15_15", rng.normal(100.0, 5.0, 15), rng.normal(103.0, 5.0, 15)))
    # Rounded: many ties (a grid's or a plateau's scores).
    cases.append(("ties_15_12", np.round(rng.normal(10.0, 1.0, 15)), np.round(rng.normal(10.5, 1.0, 12))))
    # Unequal sizes, clearly apart.
    cases.append(("apart_9_20", rng.normal(0.0, 1.0, 9), rng.normal(3.0, 1.0, 20)))
    # Identical distributions.
    cases.append(("same_20_20", rng.uniform(0.0, 1.0, 20), rng.uniform(0.0, 1.0, 20)))
    # A deterministic optimiser's single run against 15 seeds.
    cases.append(("one_vs_15", np.array([5.0]), rng.normal(5.5, 1.0, 15)))
    return cases


def holm(p):
    m = len(p)
    order = sorted(range(m), key=lambda i: p[i])
    out = [0.0] * m
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[i]))
        out[i] = running
    return out


def ert(runs):
    successes = sum(1 for r in runs if r["hit"] >= 1)
    total = sum(r["hit"] if r["hit"] >= 1 else r["evaluations"] for r in runs)
    return total / successes if successes else "inf"


def main():
    doc = {"rank_sum": [], "quantiles": [], "holm": [], "ert": []}
    for name, x, y in samples():
        res = stats.mannwhitneyu(x, y, alternative="two-sided", method="asymptotic",
                                 use_continuity=True)
        u = float(res.statistic)
        doc["rank_sum"].append({
            "name": name, "x": [float(v) for v in x], "y": [float(v) for v in y],
            "u": u, "p_value": float(res.pvalue), "a12": u / (len(x) * len(y)),
            "z": float(stats.norm.isf(res.pvalue / 2.0)),
        })
    rng = np.random.default_rng(7)
    for n in (1, 2, 5, 15):
        values = [float(v) for v in rng.normal(0.0, 1.0, n)]
        qs = [0.0, 0.1, 0.25, 0.5, 0.75, 0.9, 1.0]
        expected = [float(np.quantile(values, q, method="linear")) for q in qs]
        check = [float(v) for v in mstats.mquantiles(values, prob=qs, alphap=1, betap=1)]
        assert all(math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-12) for a, b in zip(expected, check))
        doc["quantiles"].append({"values": values, "q": qs, "expected": expected})
    for p in ([0.01, 0.04, 0.03, 0.005], [0.5, 0.5, 0.2], [0.001] * 6 + [0.9], [0.04]):
        doc["holm"].append({"p": p, "expected": holm(p)})
    ert_cases = [
        [{"evaluations": 100, "hit": 10}, {"evaluations": 100, "hit": 30}, {"evaluations": 100, "hit": -1}],
        [{"evaluations": 50, "hit": -1}, {"evaluations": 80, "hit": -1}],
        [{"evaluations": 480, "hit": 480}],
        [{"evaluations": 60, "hit": 7}, {"evaluations": 40, "hit": -1}, {"evaluations": 60, "hit": 1},
         {"evaluations": 60, "hit": 60}],
    ]
    for runs in ert_cases:
        doc["ert"].append({"runs": runs, "expected": ert(runs)})
    json.dump(doc, sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
