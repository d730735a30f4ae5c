#!/usr/bin/env python3
"""Where a source's missing track coverage goes (issue 14, the mixed site's hovering D2).

Reads the simulator's truth, the tracks' JSON lines and (optionally) the DOA lines of one run and
sorts every tick of one source into one cause, with eval's own rules for "covered" (counted
tracks = confirmed or coasting, assigned to live sources by least total distance within the
association gate, covered within the coverage gate). A tick that is not covered is, in this order:

  off_truth     a counted track is assigned to the source but lies beyond the coverage gate
  on_ray_off    a counted track lies on the source's bearing from the ray array (within
                --bearing-deg) but off in range: the range along that array's ray is wrong
  tentative     a tentative track lies within the association gate (not confirmed yet)
  no_doa        no DOA of any array within --bearing-deg of the source in the last --doa-memory-s
  one_array     DOAs of the source from one array only (nothing to triangulate)
  no_track      DOAs from two or more arrays, yet no track near the source

For on_ray_off and off_truth ticks it prints the signed range error along the ray array's ray
(negative: towards the array) against the track's stated std along that ray (from its diagonal
position_std_m: correlations are not on the track line, so this is an approximation). It also
lists every track that followed the source: birth, confirmation, end, the arrays whose DOAs near
the source arrived within --init-window-s of its birth, and its covered share.

Plain Python 3, no third-party modules. Example:
  scripts/coverage-breakdown.py --truth S/truth.json --tracks S/T.jsonl --doa S/doas.jsonl \
      --source D2 --ray-array N2
"""
import argparse
import itertools
import json
import math
import sys
from bisect import bisect_left


def unit(v):
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v] if n > 0 else v


def angle_deg(a, b):
    a, b = unit(a), unit(b)
    c = max(-1.0, min(1.0, sum(x * y for x, y in zip(a, b))))
    return math.degrees(math.acos(c))


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


def norm(v):
    return math.sqrt(sum(x * x for x in v))


class Source:
    def __init__(self, record, arrays):
        self.id = record["id"]
        self.t = record["t"]
        self.p = record["position_m"]
        self.doa = {a: record["doa"][a]["direction"] for a in record.get("doa", {}) if a in arrays}

    def index(self, t):
        i = bisect_left(self.t, t)
        return min(max(i, 0), len(self.t) - 1)

    def alive(self, t):
        return self.t and self.t[0] - 1e-9 <= t <= self.t[-1] + 1e-9

    def position(self, t):
        i = bisect_left(self.t, t)
        if i <= 0:
            return self.p[0]
        if i >= len(self.t):
            return self.p[-1]
        t0, t1 = self.t[i - 1], self.t[i]
        w = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
        return [a + w * (b - a) for a, b in zip(self.p[i - 1], self.p[i])]

    def direction(self, array, t):
        return self.doa[array][self.index(t)]


def best_assignment(tracks, sources, t, gate_m):
    """Least total distance among the assignments with the most pairs (eval's Hungarian)."""
    options = []
    for s in sources:
        row = [None]
        for k, tr in enumerate(tracks):
            d = norm(sub(tr["position_m"], s.position(tr["t"])))
            if d <= gate_m:
                row.append((k, d))
        options.append(row)
    best, best_key = None, None
    for combo in itertools.product(*options):
        used = [c[0] for c in combo if c is not None]
        if len(used) != len(set(used)):
            continue
        key = (-len(used), sum(c[1] for c in combo if c is not None))
        if best_key is None or key < best_key:
            best, best_key = combo, key
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--truth", required=True)
    parser.add_argument("--tracks", required=True)
    parser.add_argument("--doa", help="DOA lines of the run (replay --doa-out)")
    parser.add_argument("--source", default="D2")
    parser.add_argument("--ray-array", help="array whose ray the range is judged along "
                        "(default: the one with most DOAs near the source)")
    parser.add_argument("--tick-s", type=float, default=0.1)
    parser.add_argument("--gate-m", type=float, default=10.0, help="eval's association gate")
    parser.add_argument("--coverage-gate-m", type=float, default=5.0)
    parser.add_argument("--bearing-deg", type=float, default=3.0)
    parser.add_argument("--doa-memory-s", type=float, default=0.5)
    parser.add_argument("--init-window-s", type=float, default=0.3)
    args = parser.parse_args()

    truth = json.load(open(args.truth))
    centres = {a: v["centre_m"] for a, v in truth["arrays"].items()}
    end_s = min([v.get("recording_end_s", 1e18) for v in truth["arrays"].values()] +
                [truth.get("duration_s", 1e18)])
    sources = [Source(s, centres) for s in truth["sources"]]
    target = next((s for s in sources if s.id == args.source), None)
    if target is None:
        sys.exit(f"coverage-breakdown: no source {args.source} in {args.truth}")

    by_tick = {}
    for line in open(args.tracks):
        line = line.strip()
        if not line:
            continue
        tr = json.loads(line)
        if "position_m" not in tr:
            continue
        by_tick.setdefault(round(tr["t"] / args.tick_s), []).append(tr)

    # DOAs near the target, per array, by time.
    near = {a: [] for a in centres}
    if args.doa:
        for line in open(args.doa):
            d = json.loads(line)
            a = d.get("array")
            if a not in centres or d.get("ambiguity", "none") != "none":
                continue
            if target.alive(d["t"]) and angle_deg(d["direction"],
                                                  target.direction(a, d["t"])) <= args.bearing_deg:
                near[a].append(d["t"])
    ray_array = args.ray_array or max(near, key=lambda a: len(near[a]))

    def doa_arrays(t0, t1):
        out = []
        for a, times in near.items():
            i = bisect_left(times, t0)
            if i < len(times) and times[i] <= t1:
                out.append(a)
        return out

    counts = {k: 0 for k in ("covered", "off_truth", "on_ray_off", "tentative", "no_doa",
                             "one_array", "no_track")}
    ray_rows = []  # (t, id, along-ray error, std along ray, cross-ray error)
    lives = {}  # id -> dict
    start_s = target.t[0]
    ticks = int(math.floor((min(end_s, target.t[-1]) - start_s) / args.tick_s + 1e-9)) + 1
    timeline = []
    for k in range(ticks):
        t = start_s + k * args.tick_s
        lines = by_tick.get(round(t / args.tick_s), [])
        for tr in lines:
            life = lives.setdefault(tr["id"], {"first": tr["t"], "confirmed": None,
                                               "last": tr["t"], "covered": 0, "near": 0})
            life["last"] = tr["t"]
            if tr["status"] != "tentative" and life["confirmed"] is None:
                life["confirmed"] = tr["t"]
        counted = [tr for tr in lines if tr["status"] in ("confirmed", "coasting")]
        alive = [s for s in sources if s.alive(t)]
        combo = best_assignment(counted, alive, t, args.gate_m)
        mine = None
        if combo is not None and target in alive:
            mine = combo[alive.index(target)]
        centre = centres[ray_array]
        truth_p = target.position(t)
        ray = unit(sub(truth_p, centre))
        cause = None
        if mine is not None:
            tr = counted[mine[0]]
            if mine[1] <= args.coverage_gate_m:
                cause = "covered"
                lives[tr["id"]]["covered"] += 1
            else:
                cause = "off_truth"
        if cause is None:
            on_ray = [tr for tr in counted
                      if angle_deg(sub(tr["position_m"], centre), ray) <= args.bearing_deg]
            if on_ray:
                cause = "on_ray_off"
        if cause in ("off_truth", "on_ray_off"):
            tr = counted[mine[0]] if cause == "off_truth" else min(
                on_ray, key=lambda x: angle_deg(sub(x["position_m"], centre), ray))
            error = sub(tr["position_m"], truth_p)
            along = sum(e * u for e, u in zip(error, ray))
            cross = norm([e - along * u for e, u in zip(error, ray)])
            std = math.sqrt(sum((u * s) ** 2 for u, s in zip(ray, tr["position_std_m"])))
            ray_rows.append((t, tr["id"], along, std, cross))
            lives[tr["id"]]["near"] += 1
        if cause is None:
            if any(tr["status"] == "tentative" and
                   norm(sub(tr["position_m"], truth_p)) <= args.gate_m for tr in lines):
                cause = "tentative"
            elif args.doa:
                heard = doa_arrays(t - args.doa_memory_s, t)
                cause = "no_doa" if not heard else ("one_array" if len(heard) == 1 else
                                                    "no_track")
            else:
                cause = "no_track"
        counts[cause] += 1
        timeline.append((t, cause))

    print(f"source {target.id}, ray array {ray_array}, {ticks} ticks of {args.tick_s} s")
    print("cause        ticks  share")
    for cause, n in counts.items():
        print(f"{cause:<12} {n:5d} {100.0 * n / max(ticks, 1):6.1f} %")
    # Runs of one cause, so a reader sees where in the run each sits.
    print("\nruns (start-end s: cause) of the uncovered ticks:")
    runs, current = [], None
    for t, cause in timeline:
        if current and current[2] == cause and abs(t - current[1] - args.tick_s) < 1e-6:
            current[1] = t
        else:
            if current:
                runs.append(current)
            current = [t, t, cause]
    if current:
        runs.append(current)
    for a, b, cause in runs:
        if cause != "covered":
            print(f"  {a:6.1f}-{b:6.1f} s: {cause}")
    if ray_rows:
        print(f"\noff-range ticks: error along {ray_array}'s ray (negative: towards it) "
              "against the stated std along it (diagonal), per second")
        print("   t_s  track  along_m  std_m  ratio  cross_m")
        last = None
        for t, tid, along, std, cross in ray_rows:
            if last is not None and int(t) == int(last):
                continue
            last = t
            print(f"{t:6.1f} {tid:6d} {along:8.1f} {std:6.2f} {abs(along) / max(std, 1e-9):6.1f}"
                  f" {cross:8.1f}")
    print("\ntracks that followed it (covered ticks or off along the ray):")
    print("   id  born_s  confirmed_s  last_s  covered_ticks  off_ticks  arrays near it at birth")
    for tid, life in sorted(lives.items()):
        if life["covered"] == 0 and life["near"] == 0:
            continue
        at_birth = doa_arrays(life["first"] - args.init_window_s, life["first"] + 0.05)
        conf = f"{life['confirmed']:.1f}" if life["confirmed"] is not None else "-"
        print(f"{tid:5d} {life['first']:7.1f} {conf:>12} {life['last']:7.1f} {life['covered']:14d}"
              f" {life['near']:10d}  {' '.join(at_birth) if args.doa else '?'}")
    if args.doa:
        print("\nDOAs within the bearing gate of the source, per array (per second of run):")
        for a, times in near.items():
            print(f"  {a}: {len(times)} ({len(times) / max(end_s, 1e-9):.1f}/s)")


if __name__ == "__main__":
    main()
