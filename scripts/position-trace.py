#!/usr/bin/env python3
"""Where a lone drone's position error comes from (issue 14, docs/doa.md "Position error beside a
loud non-drone"): per time window, each array's DOAs within 5 deg of the drone's truth direction
(eval's: the direction the sound arrives from) against it: count, median error, bias (mean
az*cos(el) / el error) and spread (their std), the mean normalised innovation
e^T C^-1 e with C the line's own azel_std_deg / azel_correlation (2 when honest), the reported
stds; and the track's RMSE over the confirmed/coasting reports nearest the truth (within 10 m),
the rms of its error along each array's ray to the drone (the range each array does not see) and
the mean diagonal position NEES (3 when honest). The last row is the whole run.

Usage: scripts/position-trace.py [--source=ID] DIR TRACKS [DOAS] [WINDOW_S]   (DIR: a `sim`
output with truth.json and, unless DOAS is given, doas.jsonl, as scripts/scene-draws.sh leaves
them; the drone is the truth's source ID, D1 unless --source says; WINDOW_S 5). Needs python3
with numpy (Debian: python3-numpy).
"""
import json, math, sys, bisect
import numpy as np
source_id = next((a.split("=", 1)[1] for a in sys.argv[1:] if a.startswith("--source=")), "D1")
args = [a for a in sys.argv[1:] if not a.startswith("--source=")]
d, tracks_path = args[0], args[1]
doas_path = args[2] if len(args) > 2 else f"{d}/doas.jsonl"
win = float(args[3]) if len(args) > 3 else 5.0
truth = json.load(open(f"{d}/truth.json"))
rate = truth["rate_hz"]
drone = [s for s in truth["sources"] if s["id"] == source_id][0]
P = np.array(drone["position_m"])
def truth_at(t):
    x = t * rate; k = int(math.floor(x)); f = x - k
    k = max(0, min(k, len(P) - 2))
    return P[k] * (1 - f) + P[k + 1] * f
D = {a: np.array(v["direction"]) for a, v in drone["doa"].items()}
def dir_at(a, t):
    x = t * rate; k = int(math.floor(x)); f = x - k
    k = max(0, min(k, len(D[a]) - 2))
    u = D[a][k] * (1 - f) + D[a][k + 1] * f
    return u / np.linalg.norm(u)
centres = {a: np.array(v["centre_m"]) for a, v in truth["arrays"].items()}
def azel(v):
    return math.degrees(math.atan2(v[1], v[0])), math.degrees(math.atan2(v[2], math.hypot(v[0], v[1])))
def wrap(a):
    return (a + 180) % 360 - 180
rows = {}
for line in open(doas_path):
    r = json.loads(line)
    a = r["array"]; t = r["t"]
    u = dir_at(a, t)
    v = np.array(r["direction"])
    ang = math.degrees(math.acos(max(-1, min(1, float(u @ v)))))
    if ang > 5:
        continue
    taz, tel = azel(u)
    daz = wrap(r["azimuth_deg"] - taz); dele = r["elevation_deg"] - tel
    saz, sel = r["azel_std_deg"]; rho = r["azel_correlation"]
    C = np.array([[saz * saz, rho * saz * sel], [rho * saz * sel, sel * sel]])
    e = np.array([daz, dele])
    nis = float(e @ np.linalg.solve(C, e))
    rows.setdefault(a, []).append((t, ang, daz * math.cos(math.radians(tel)), dele, nis, saz * math.cos(math.radians(tel)), sel))
# Tracks: per tick the counted track nearest the truth within 10 m.
ticks = {}
for line in open(tracks_path):
    r = json.loads(line)
    if r["status"] == "tentative":
        continue
    t = round(r["t"], 3)
    e = np.array(r["position_m"]) - truth_at(r["t"])
    n = float(np.linalg.norm(e))
    if n < 10 and (t not in ticks or n < ticks[t][0]):
        std = np.array(r["position_std_m"])
        ticks[t] = (n, e, float(np.sum((e / std) ** 2)))
tt = sorted(ticks)
def split(t):
    return int(t // win)
nwin = int(truth["duration_s"] // win)
print(f"window | " + " | ".join(f"{a}: n, med err deg, bias az*cos el / el deg, spread az/el deg, mean NIS (2), rep std az/el" for a in sorted(rows)) + " | track: ticks, RMSE m, err along each array's ray to the drone, " + " / ".join(sorted(centres)) + " (m rms), mean NEES(3)")
for w in list(range(nwin)) + ["all"]:
    cells = []
    for a in sorted(rows):
        x = np.array([r for r in rows[a] if w == "all" or split(r[0]) == w])
        if len(x) == 0:
            cells.append("0"); continue
        cells.append(f"{len(x)}, {np.median(x[:,1]):.3f}, {x[:,2].mean():+.3f}/{x[:,3].mean():+.3f}, {x[:,2].std():.3f}/{x[:,3].std():.3f}, {x[:,4].mean():.2f} (med {np.median(x[:,4]):.2f}), {np.median(x[:,5]):.3f}/{np.median(x[:,6]):.3f}")
    sel = [ticks[t] for t in tt if w == "all" or split(t) == w]
    if sel:
        errs = np.array([s[0] for s in sel]); E = np.array([s[1] for s in sel])
        # components along each array's ray to the drone (range error from that array)
        comps = []
        for a in sorted(centres):
            along = []
            for t in [t for t in tt if w == "all" or split(t) == w]:
                u = truth_at(t) - centres[a]; u /= np.linalg.norm(u)
                along.append(float(ticks[t][1] @ u))
            comps.append(math.sqrt(np.mean(np.square(along))))
        nees = np.mean([s[2] for s in sel])
        cells.append(f"{len(sel)}, {math.sqrt(np.mean(errs**2)):.3f}, " + " / ".join(f"{c:.3f}" for c in comps) + f", {nees:.2f}")
    else:
        cells.append("0")
    label = "all" if w == "all" else f"{w*win:.0f}-{(w+1)*win:.0f} s"
    print(f"| {label} | " + " | ".join(cells) + " |")
