#!/usr/bin/env python3
"""(issue 14, session 24) One drone's DOAs at one array against the truth, its error split by time window: per window of
WINDOW_S the mean error (az*cos el, el: the bias a fusion cannot average away within that time)
and the scatter about that mean; printed: DOA count and median error, the whole run's mean, the
rms over windows of the window means (count-weighted) and the rms scatter within windows.

Usage: scripts/doa-bias-spread.py DIR ARRAY [DOAS] [WINDOW_S=2]   (DIR: a sim output with truth.json;
DOAS default DIR/doas.jsonl; the drone D1; DOAs within 5 deg of its truth direction count).
"""
import json, math, sys
import numpy as np
d, array = sys.argv[1], sys.argv[2]
doas = sys.argv[3] if len(sys.argv) > 3 else f"{d}/doas.jsonl"
win = float(sys.argv[4]) if len(sys.argv) > 4 else 2.0
truth = json.load(open(f"{d}/truth.json")); rate = truth["rate_hz"]
D = np.array([s for s in truth["sources"] if s["id"] == "D1"][0]["doa"][array]["direction"])
def dir_at(t):
    x = t * rate; k = max(0, min(int(x), len(D) - 2)); f = x - k
    u = D[k] * (1 - f) + D[k + 1] * f; return u / np.linalg.norm(u)
rows = []
for line in open(doas):
    r = json.loads(line)
    if r["array"] != array: continue
    u = dir_at(r["t"]); v = np.array(r["direction"])
    ang = math.degrees(math.acos(max(-1, min(1, float(u @ v)))))
    if ang > 5: continue
    taz = math.degrees(math.atan2(u[1], u[0])); tel = math.degrees(math.asin(max(-1, min(1, u[2]))))
    daz = (r["azimuth_deg"] - taz + 180) % 360 - 180
    rows.append((r["t"], ang, daz * math.cos(math.radians(tel)), r["elevation_deg"] - tel))
x = np.array(rows); w = np.floor(x[:, 0] / win)
means, scatter = [], []
for k in np.unique(w):
    s = x[w == k][:, 2:4]
    means.append((len(s), *s.mean(0))); scatter.append(((s - s.mean(0)) ** 2).sum(0))
m = np.array(means); n = m[:, 0].sum()
bias = np.sqrt((m[:, 0:1] * m[:, 1:3] ** 2).sum(0) / n); spread = np.sqrt(np.array(scatter).sum(0) / n)
print(f"{array} n {len(x)}, median {np.median(x[:,1]):.3f} deg, run mean {x[:,2].mean():+.3f} / {x[:,3].mean():+.3f}, "
      f"window ({win:g} s) bias rms {bias[0]:.3f} / {bias[1]:.3f}, spread within {spread[0]:.3f} / {spread[1]:.3f} deg (az*cos el / el)")
