#!/usr/bin/env python3
"""Is a track's covariance honest, by track age? (issue 17, docs/fusion.md "Where the outliers land")

For one e2e scene and one likelihood run of scripts/likelihood-compare.sh: every confirmed or
coasting report of tracks.jsonl against the nearest truth source (within 30 m) at its time, the
diagonal position NEES sum_j (error_j / position_std_j)^2 (3 when honest, ignoring the
correlations the report does not carry), averaged per track age (time since the track's first
report): 0-2, 2-5, 5-10, 10-20, 20+ s, with the share beyond the chi-square 3-dof 99.9 % point.

Usage: scripts/track-nees.py SCENE LIKELIHOOD  (after `ctest -R 'e2e\\.'` and likelihood-compare.sh;
BUILD and WORK as there)
"""
import bisect
import collections
import json
import math
import os
import sys

scene, likelihood = sys.argv[1], sys.argv[2]
build = os.environ.get("BUILD", "build/release")
work = os.environ.get("WORK", "build/likelihood-compare")
truth = json.load(open(f"{build}/tests/e2e/{scene}/truth.json"))
rate = truth["rate_hz"]
first = {}
buckets = collections.defaultdict(lambda: [0, 0.0, 0])
for line in open(f"{work}/{scene}/{likelihood.replace(':', '_').replace('=', '_')}/tracks.jsonl"):
    report = json.loads(line)
    first.setdefault(report["id"], report["t"])
    if report["status"] == "tentative":
        continue
    k = int(round(report["t"] * rate))
    best = None
    for source in truth["sources"]:
        if k >= len(source["position_m"]):
            continue
        error = [p - q for p, q in zip(report["position_m"], source["position_m"][k])]
        norm = math.sqrt(sum(e * e for e in error))
        if best is None or norm < best[0]:
            best = (norm, error)
    if best is None or best[0] > 30.0:
        continue
    nees = sum((e / s) ** 2 for e, s in zip(best[1], report["position_std_m"]))
    ages = (0, 2, 5, 10, 20)
    age = ages[bisect.bisect_right(ages, report["t"] - first[report["id"]]) - 1]
    bucket = buckets[age]
    bucket[0] += 1
    bucket[1] += nees
    bucket[2] += nees > 16.27
print(scene, likelihood, "; ".join(
    f"age >= {age} s: {n} reports, NEES {total / n:.2f}, beyond 99.9 % {100 * out / n:.1f} %"
    for age, (n, total, out) in sorted(buckets.items())))
