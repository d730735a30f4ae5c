#!/usr/bin/env python3
"""Per drone and array, a scene's DOAs against the truth (issue 14, docs/doa.md "Position error
beside a loud non-drone"): each DOA within 5 deg of its nearest truth source (the drones) counts
for that drone: count, median error, bias (mean az*cos(el) / el error), spread (their std), the
normalised innovation e^T C^-1 e against the line's own azel_std_deg / azel_correlation (mean and
median; 2 when honest).

Usage: scripts/drone-doa-errors.py DIR [DOAS]  (DIR with truth.json and, unless DOAS is given,
doas.jsonl: scripts/scene-draws.sh). Needs numpy (Debian: python3-numpy).
"""
import json, math, sys
import numpy as np
d = sys.argv[1]; doas = sys.argv[2] if len(sys.argv) > 2 else f"{d}/doas.jsonl"
truth = json.load(open(f"{d}/truth.json")); rate = truth["rate_hz"]
def dir_at(s, a, t):
    D = s["doa"][a]["direction"]; x = t * rate; k = max(0, min(int(x), len(D) - 2)); f = x - k
    u = np.array(D[k]) * (1 - f) + np.array(D[k + 1]) * f; n = np.linalg.norm(u)
    return u / n if n > 0 else None
rows = {}
for line in open(doas):
    r = json.loads(line); v = np.array(r["direction"]); best = None
    for s in truth["sources"]:
        if r["array"] not in s["doa"]: continue
        u = dir_at(s, r["array"], r["t"])
        if u is None: continue
        ang = math.degrees(math.acos(max(-1, min(1, float(u @ v)))))
        if best is None or ang < best[0]: best = (ang, s["id"], u)
    if best is None or best[0] > 5: continue
    ang, sid, u = best
    taz = math.degrees(math.atan2(u[1], u[0])); tel = math.degrees(math.asin(max(-1, min(1, u[2]))))
    daz = (r["azimuth_deg"] - taz + 180) % 360 - 180; de = r["elevation_deg"] - tel
    saz, sel = r["azel_std_deg"]; rho = r["azel_correlation"]
    C = np.array([[saz * saz, rho * saz * sel], [rho * saz * sel, sel * sel]]); e = np.array([daz, de])
    rows.setdefault((sid, r["array"]), []).append((ang, daz * math.cos(math.radians(tel)), de, float(e @ np.linalg.solve(C, e))))
for key in sorted(rows):
    x = np.array(rows[key])
    print(f"{key[0]} {key[1]}: n {len(x)}, median {np.median(x[:,0]):.3f} deg, bias {x[:,1].mean():+.3f} / {x[:,2].mean():+.3f}, spread {x[:,1].std():.3f} / {x[:,2].std():.3f}, NIS mean {x[:,3].mean():.2f} median {np.median(x[:,3]):.2f}")
