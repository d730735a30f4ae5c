#!/usr/bin/env python3
"""Attribute a drone's excess position error to an array (issue 14, docs/doa.md "Position error
beside a loud non-drone"): a DOA file made of a scene's DOAs with some arrays' drone DOAs (within
5 deg of a truth source's direction, the truth's sources being the drones) replaced by those
arrays' drone DOAs from the same scene rendered without the non-drone sources (same seed). Fed to
the fusion alone (`replay --doa-in`), the RMSE left says what those arrays' degradation costs.

Usage: scripts/doa-swap.py WITH_DIR ALONE_DIR OUT MODE, WITH_DIR/ALONE_DIR holding truth.json and
doas.jsonl (scripts/scene-draws.sh), MODE one of
  A1 | N1,N3 | ...  these arrays' drone DOAs from ALONE_DIR
  drones-only       every DOA not within 5 deg of a drone removed (the non-drones' DOAs)
  inflate:A1=K,...  each named array's drone DOAs' azel_std_deg multiplied by K (ALONE_DIR unused)
Needs python3 with numpy (Debian: python3-numpy).
"""
import json
import math
import sys

import numpy as np

with_dir, alone_dir, out, mode = sys.argv[1:5]
truth = json.load(open(f"{with_dir}/truth.json"))
rate = truth["rate_hz"]


def near_drone(doa):
    for source in truth["sources"]:
        if doa["array"] not in source["doa"]:
            continue
        directions = source["doa"][doa["array"]]["direction"]
        x = doa["t"] * rate
        k = max(0, min(int(x), len(directions) - 2))
        f = x - k
        u = np.array(directions[k]) * (1 - f) + np.array(directions[k + 1]) * f
        norm = np.linalg.norm(u)
        if norm > 0 and math.degrees(math.acos(max(-1.0, min(1.0, float(u @ np.array(doa["direction"])) / norm)))) <= 5:
            return True
    return False


scene = [json.loads(line) for line in open(f"{with_dir}/doas.jsonl")]
if mode == "drones-only":
    kept = [doa for doa in scene if near_drone(doa)]
elif mode.startswith("inflate:"):
    factors = {part.split("=")[0]: float(part.split("=")[1]) for part in mode[len("inflate:"):].split(",")}
    kept = scene
    for doa in kept:
        if doa["array"] in factors and near_drone(doa):
            doa["azel_std_deg"] = [s * factors[doa["array"]] for s in doa["azel_std_deg"]]
else:
    arrays = mode.split(",")
    alone = [json.loads(line) for line in open(f"{alone_dir}/doas.jsonl")]
    kept = [doa for doa in scene if not (doa["array"] in arrays and near_drone(doa))]
    kept += [doa for doa in alone if doa["array"] in arrays and near_drone(doa)]
kept.sort(key=lambda doa: doa["t"])
with open(out, "w") as f:
    for doa in kept:
        f.write(json.dumps(doa) + "\n")
