#!/usr/bin/env python3
"""(issue 14, session 24) What the static cancel's projection does to a drone's DOA with no noise
at all, at one array of a ground-interferer render (docs/doa.md "A1 beside the generator"): the
drone's plane wave b (the truth's direction over time) in its comb's bins (harmonics of its blade
pass in the band), projected orthogonal to the generator's steering vector a (G1's near field:
direct path + ground image of the scenario's reflection coefficient), P b = b - a (a^H b); per
truth sample each pair's GCC-PHAT peak over those bins, the LS direction from the six pair lags,
its angle to the truth. Printed: that error (median, p90, mean az*cos el / el) projected and
refilled (P b + a c, c equalising the mics' moduli: StaticSourceCancel's refill), |a^H b|^2 and
the drone-generator separation. With DOAS, each of the array's drone DOAs (within 5 deg) against
the model's projected error at its time: correlation per axis (does the projection explain the
measured error?).

(session 26) --drone-echo: the drone as the simulator renders it instead of a plane wave: from
its true position (truth.json), near field, direct path + its ground image of the scenario's
reflection coefficient; the truth direction is then the position's from the array's centre (the
DOA truth lags it by the sound's travel time), and a first line gives plain GCC-PHAT's error on
those bins with no generator and no projection. --null-steered (with or without --drone-echo):
also, every 100th truth sample, the direction that maximises sum_k |(P v)^H x|^2 / |P v|^2 (v
the plane wave of a direction on a 0.05 deg grid within 2 deg of the truth: the null-steered
search, no refill) and, for comparison, sum_k |v^H x|^2 / |v|^2 on the same grid with no
projection; with --drone-echo also with v the direct path plus its ground image of a source at
the truth's range (and at 1.2x it) in each grid direction. --echo-refill=DEG (with
--drone-echo): also the refill made on the echo's terms: the mics' moduli equalised after dividing each by its echo comb |1 + g e^{-j w Delta_m}| (g the
scene's reflection coefficient, Delta_m from the truth position with its elevation moved by DEG
degrees: the node would know the drone's direction only to its own error), and the error after
the echo is divided out, beside the drone's own and the plain refill's.

--snr-db=DB: the mics' noise added to the drone's bins (isotropic, DB under the drone's power
in each bin, seeded) before the projection, for the projected and refilled rows (the generator
is still cancelled exactly: its a is the true one).

Usage: scripts/projection-bias.py [--drone-echo] [--null-steered] [--echo-refill=DEG]
                                  [--snr-db=DB] DIR [ARRAY=A1] [DOAS]
(DIR: a scene-draws.sh render with scenario.json and truth.json, or `dronetrack sim SCENARIO
--out DIR` with the scenario copied in as DIR/scenario.json). Needs numpy (Debian:
python3-numpy; a pyenv python may lack it: /usr/bin/python3).
"""
import json, math, sys
import numpy as np
flags = {a for a in sys.argv[1:] if a.startswith("--")}
args = [a for a in sys.argv[1:] if not a.startswith("--")]
drone_echo = "--drone-echo" in flags; null_steered = "--null-steered" in flags
echo_refill = [float(a.split("=", 1)[1]) for a in flags if a.startswith("--echo-refill=")]
snr_db = [float(a.split("=", 1)[1]) for a in flags if a.startswith("--snr-db=")]
d = args[0]; array = args[1] if len(args) > 1 else "A1"
doas = args[2] if len(args) > 2 else None
sc = json.load(open(f"{d}/scenario.json")); truth = json.load(open(f"{d}/truth.json"))
c = sc["site"]["speed_of_sound_mps"]
site = [a for a in sc["site"]["arrays"] if a["id"] == array][0]
mics = np.array(site["mics_m"]) + np.array(site["position_m"])  # the scene's arrays: yaw 0
g = np.array([s for s in sc["sources"] if s["id"] == "G1"][0]["trajectory"]["position_m"], float)
refl = sc.get("ground", {}).get("reflection_coefficient", 0.0)
drone = [s for s in sc["sources"] if s["kind"] == "drone"][0]
low, high = sc["site"]["doa"]["bands_hz"][0]; fundamental = drone["signal"]["blade_pass_hz"]
freqs = np.array([k * fundamental for k in range(1, 400) if low <= k * fundamental <= high], float)
def paths(sources):
    """Each mic's distance to the source(s) (..., 3) and to its ground image: (..., mics) each."""
    sources = np.asarray(sources)[..., None, :]
    return (np.linalg.norm(mics - sources, axis=-1),
            np.linalg.norm(mics - sources * np.array([1, 1, -1]), axis=-1))
def direct_and_echo(sources):
    """Direct path + ground image (spherical spreading) in the comb bins: (..., bins, mics)."""
    direct, image = paths(sources)
    def tone(r): return np.exp(-2j * np.pi * freqs[:, None] * r[..., None, :] / c) / r[..., None, :]
    return tone(direct) + refl * tone(image)
A = direct_and_echo(g); A = A / np.linalg.norm(A, axis=1)[:, None]  # the generator's unit vectors
pairs = [(i, j) for i in range(len(mics)) for j in range(i + 1, len(mics))]
M = np.array([mics[j] - mics[i] for i, j in pairs])
offsets = np.linspace(-3e-4, 3e-4, 601)
def direction(X, u):  # GCC-PHAT peak per pair within 0.3 ms of the truth's lag, LS direction
    lags = []
    for p, (i, j) in enumerate(pairs):
        cross = X[:, i] * np.conj(X[:, j]); cross = cross / np.maximum(np.abs(cross), 1e-300)
        t = M[p] @ u / c + offsets
        lags.append(t[np.argmax(np.real(np.exp(2j * np.pi * np.outer(t, freqs)) @ cross))])
    e, *_ = np.linalg.lstsq(M / c, np.array(lags), rcond=None); return e / np.linalg.norm(e)
def refill(y, a):  # Gauss-Newton on (Re c, Im c) from 0, as StaticSourceCancel::refill_plane_wave
    cc = 0j
    for _ in range(8):
        x = y + a * cc; p = np.abs(x) ** 2
        J = np.stack([2 * np.real(np.conj(x) * a), -2 * np.imag(np.conj(x) * a)], 1); J = J - J.mean(0)
        step, *_ = np.linalg.lstsq(J, -(p - p.mean()), rcond=None); cc += step[0] + 1j * step[1]
    return y + a * cc  # no generator in the model: the guard on the bin's own power never binds
def azel(u): return math.degrees(math.atan2(u[1], u[0])), math.degrees(math.asin(max(-1, min(1, u[2]))))
def errors(u, e):
    taz, tel = azel(u); eaz, eel = azel(e)
    return (math.degrees(math.acos(min(1, float(e @ u)))),
            ((eaz - taz + 180) % 360 - 180) * math.cos(math.radians(tel)), eel - tel)
rate = truth["rate_hz"]
D = np.array([s for s in truth["sources"] if s["id"] == drone["id"]][0]["doa"][array]["direction"])
def truth_dir(t):
    x = t * rate; k = max(0, min(int(x), len(D) - 2)); f = x - k
    u = D[k] * (1 - f) + D[k + 1] * f; return u / np.linalg.norm(u)
centre = mics.mean(0); towards_g = (g - centre) / np.linalg.norm(g - centre)
positions = np.array([s for s in truth["sources"] if s["id"] == drone["id"]][0]["position_m"])
def drone_bins(k):
    """The truth direction at truth sample k and the drone's unit mic vectors in the comb bins."""
    if not drone_echo:
        u = D[k] / np.linalg.norm(D[k])
        return u, np.exp(2j * np.pi * np.outer(freqs, mics @ u) / c) / math.sqrt(len(mics))
    p = positions[k]; u = (p - centre) / np.linalg.norm(p - centre)
    v = direct_and_echo(p)
    return u, v / np.linalg.norm(v, axis=1)[:, None]
rows = []; plain = []
noise_rng = np.random.default_rng(1)
for k in range(0, len(D), 25):
    u, B = drone_bins(k)
    if snr_db:  # the mics' own noise, isotropic, at snr_db under the drone's power in each bin
        sigma = math.sqrt(10 ** (-snr_db[0] / 10) / len(mics))
        B = B + sigma * (noise_rng.standard_normal(B.shape) + 1j * noise_rng.standard_normal(B.shape)) / math.sqrt(2)
    if drone_echo or snr_db: plain.append(errors(u, direction(B, u))[0])
    ab = np.sum(np.conj(A) * B, axis=1); PB = B - A * ab[:, None]
    R = np.array([refill(PB[q], A[q]) for q in range(len(freqs))])
    rows.append((*errors(u, direction(PB, u)), *errors(u, direction(R, u)), float(np.mean(np.abs(ab) ** 2)),
                 math.degrees(math.acos(float(u @ towards_g)))))
x = np.array(rows)
if drone_echo or snr_db:
    what = ("with its ground echo" if drone_echo else "") + (" and " if drone_echo and snr_db else "")
    what += f"noise {snr_db[0]:g} dB under it" if snr_db else ""
    print(f"{array} drone {what}, no generator, no projection: error median "
          f"{np.median(plain):.3f} deg, p90 {np.percentile(plain, 90):.3f}")
for name, o in (("projected", 0), ("refilled", 3)):
    print(f"{array} {name} ({len(freqs)} comb bins, {f'noise {snr_db[0]:g} dB under' if snr_db else 'no noise'}): error median {np.median(x[:,o]):.3f} deg, p90 "
          f"{np.percentile(x[:,o],90):.3f}, mean az*cos el {x[:,o+1].mean():+.3f} / el {x[:,o+2].mean():+.3f}")
print(f"mean |a^H b|^2 {x[:,6].mean():.3f}, drone-generator separation {x[:,7].min():.1f}-{x[:,7].max():.1f} deg")
if doas:
    meas, model = [], []
    for line in open(doas):
        r = json.loads(line)
        if r["array"] != array: continue
        u = truth_dir(r["t"]); v = np.array(r["direction"])
        if math.degrees(math.acos(max(-1, min(1, float(u @ v))))) > 5: continue
        meas.append(errors(u, v)[1:])
        B = np.exp(2j * np.pi * np.outer(freqs, mics @ u) / c) / math.sqrt(len(mics))
        model.append(errors(u, direction(B - A * np.sum(np.conj(A) * B, axis=1)[:, None], u))[1:])
    m = np.array(meas); p = np.array(model)
    for k, name in enumerate(("az*cos el", "el")):
        print(f"{name}: {len(m)} DOAs, corr with the projected model {np.corrcoef(m[:,k], p[:,k])[0,1]:.2f}, rms "
              f"measured {np.sqrt(np.mean(m[:,k]**2)):.3f}, model {np.sqrt(np.mean(p[:,k]**2)):.3f} deg")
if null_steered:
    def near(u, span=2.0, step=0.05):  # directions within span deg of u, step deg apart
        az, el = (math.radians(v) for v in azel(u)); out = []
        for d_el in np.arange(-span, span + 1e-9, step):
            for d_az in np.arange(-span, span + 1e-9, step):
                a_ = az + math.radians(d_az) / max(0.2, math.cos(el)); e_ = el + math.radians(d_el)
                out.append([math.cos(e_) * math.cos(a_), math.cos(e_) * math.sin(a_), math.sin(e_)])
        return np.array(out)
    def best(V, PB):  # the grid direction whose projected steering vectors fit PB best
        PV = V - A[None] * np.einsum("qm,gqm->gq", np.conj(A), V)[..., None]  # P_q v = v - a_q (a_q^H v)
        score = np.sum(np.abs(np.einsum("gqm,qm->gq", np.conj(PV), PB)) ** 2
                       / np.sum(np.abs(PV) ** 2, axis=2), axis=1)
        return np.argmax(score)
    def echo_steering(grid, distance):  # direct path + ground image of a source `distance` away
        return direct_and_echo(centre[None] + distance * grid)
    steered, unprojected, with_echo, echo_far = [], [], [], []
    for k in range(0, len(D), 100):
        u, B = drone_bins(k); grid = near(u)
        # V[g, q, m]: plane wave of grid direction g in bin q
        V = np.exp(2j * np.pi * np.einsum("q,gm->gqm", freqs, grid @ mics.T) / c)
        PB = B - A * np.sum(np.conj(A) * B, axis=1)[:, None]
        plain_score = np.sum(np.abs(np.einsum("gqm,qm->gq", np.conj(V), B)) ** 2, axis=1)
        def error(g): return math.degrees(math.acos(min(1, float(grid[g] @ u))))
        steered.append(error(best(V, PB))); unprojected.append(error(np.argmax(plain_score)))
        if drone_echo:
            distance = np.linalg.norm(positions[k] - centre)
            with_echo.append(error(best(echo_steering(grid, distance), PB)))
            echo_far.append(error(best(echo_steering(grid, 1.2 * distance), PB)))
    results = [("null-steered search", steered), ("same search, no generator, no projection", unprojected)]
    if drone_echo:
        results += [("null-steered search, the echo in its steering vectors (true range)", with_echo),
                    ("the same, its range 1.2x the truth", echo_far)]
    for name, e in results:
        print(f"{array} {name} ({len(e)} samples, 0.05 deg grid): error median {np.median(e):.3f} "
              f"deg, p90 {np.percentile(e, 90):.3f}")
if echo_refill and drone_echo:
    moved = math.radians(echo_refill[0]); rows = []
    for k in range(0, len(D), 25):
        u, B = drone_bins(k)
        offset = positions[k] - centre; flat = math.hypot(offset[0], offset[1])
        elevation = math.atan2(offset[2], flat) + moved; distance = np.linalg.norm(offset)
        guess = centre + distance * np.array([math.cos(elevation) * offset[0] / flat,
                                              math.cos(elevation) * offset[1] / flat, math.sin(elevation)])
        direct, image = paths(guess)
        E = 1 + refl * np.exp(-2j * np.pi * np.outer(freqs, image - direct) / c)  # the echo comb
        PB = B - A * np.sum(np.conj(A) * B, axis=1)[:, None]
        # (y + a c) / E with equal moduli is y / E + (a / E) c: the same c, found on the divided bins
        R = np.array([refill(PB[q] / E[q], A[q] / E[q]) * E[q] for q in range(len(freqs))])
        plain_refill = np.array([refill(PB[q], A[q]) for q in range(len(freqs))])
        rows.append((errors(u, direction(R / E, u))[0], errors(u, direction(B / E, u))[0],
                     errors(u, direction(plain_refill / E, u))[0]))
    x = np.array(rows)
    print(f"{array} echo divided out (its elevation {echo_refill[0]:+.2f} deg off): refill on the echo's "
          f"terms {np.median(x[:, 0]):.3f} deg, the drone itself {np.median(x[:, 1]):.3f}, the plain "
          f"refill {np.median(x[:, 2]):.3f} (medians)")
