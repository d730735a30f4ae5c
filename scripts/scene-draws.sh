#!/usr/bin/env bash
# Several draws of one scenario (its "seed" key changed), each rendered once, then fusion alone on
# each draw's DOAs with each DOA likelihood: the per-draw spread that one bundled draw hides
# (docs/fusion.md "Why it is not the default yet": the mixed site's D2 moves by tens of points
# between draws and with unrelated settings). Per draw: `sim` with the seed, one
# `replay --doa-out` (the DOAs), then per likelihood `replay --doa-in --audio-end-s` on a copy of
# the site whose fusion section names it (plus --fusion JSON, e.g. '{"imm_turn_mode": false}')
# and `eval`.
# --doa JSON is merged into the site's doa section for the node replay (e.g.
# '{"follow_source_tracks": true}'); its DOAs and tracks are kept apart from the default's.
# Prints one Markdown row per draw and likelihood: each drone's coverage and RMSE, id switches,
# non-drone time said `drone`, false-track share, non-drone zone entries. The recordings are kept
# (another --doa replays them).
#
# Usage: scripts/scene-draws.sh [--work DIR] [--scenario FILE] [--seeds "21 22 23"]
#                               [--likelihoods "gaussian outlier_mixture"] [--fusion JSON]
#                               [--doa JSON]
# Defaults: DIR build/scene-draws (kept: a second run reuses its renders and DOAs), the mixed
# site, seeds 21 (the bundled draw) to 26. A render and its node replay take ~1-4 minutes on
# the shared machine; a fusion-only replay ~10 s. Needs build/release/dronetrack (or
# $DRONETRACK_BINARY) and python3.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
work=build/scene-draws
scenario=config/scenarios/mixed-site.json
seeds="21 22 23 24 25 26"
likelihoods="gaussian outlier_mixture"
fusion="{}"
doa="{}"
# Every option is --NAME VALUE setting the variable NAME.
while [[ $# -gt 0 ]]; do
  option=${1#--}
  if [[ $# -lt 2 || " work scenario seeds likelihoods fusion doa " != *" $option "* ]]; then
    echo "scene-draws.sh: bad argument '$1' (see the header for usage)" >&2
    exit 2
  fi
  printf -v "$option" '%s' "$2"
  shift 2
done
binary=${DRONETRACK_BINARY:-$PWD/build/release/dronetrack}
[[ -x "$binary" ]] || { echo "scene-draws.sh: $binary not built" >&2; exit 1; }
[[ -f "$scenario" ]] || { echo "scene-draws.sh: no scenario $scenario" >&2; exit 1; }
mkdir -p "$work"
name=$(basename "$scenario" .json)

echo "| draw (seed) | likelihood | coverage / RMSE per drone | id switches | non-drone said drone | false-track | non-drone zone entries |"
echo "|---|---|---|---|---|---|---|"
for seed in $seeds; do
  dir=$work/$name-$seed
  mkdir -p "$dir"
  if [[ ! -f "$dir/truth.json" ]]; then
    python3 - "$scenario" "$dir/scenario.json" "$seed" <<'PY'
import json, sys
scenario = json.load(open(sys.argv[1]))
scenario["seed"] = int(sys.argv[3])
json.dump(scenario, open(sys.argv[2], "w"), indent=1)
PY
    "$binary" sim "$dir/scenario.json" --out "$dir" >/dev/null 2>"$dir/sim.log"
  fi
  # The node's settings name the DOAs (and what is made from them): the default's are doas.jsonl.
  variant=""
  [[ "$doa" == "{}" ]] || variant=-$(printf '%s' "$doa" | md5sum | cut -c1-8)
  doas=$dir/doas$variant.jsonl
  if [[ ! -f "$doas" ]]; then
    python3 - "$dir/site.json" "$dir/site-node$variant.json" "$doa" <<'PY'
import json, sys
site = json.load(open(sys.argv[1]))
site.setdefault("doa", {}).update(json.loads(sys.argv[3]))
json.dump(site, open(sys.argv[2], "w"), indent=1)
PY
    "$binary" replay "$dir/site-node$variant.json" --doa-out "$doas" --tracks-out /dev/null \
      2>"$dir/replay$variant.log"
  fi
  for likelihood in $likelihoods; do
    site=$dir/site-$likelihood$variant.json
    python3 - "$dir/site.json" "$site" "$likelihood" "$fusion" <<'PY'
import json, sys
site = json.load(open(sys.argv[1]))
fusion = site.setdefault("fusion", {})
fusion["likelihood"] = sys.argv[3]
fusion.update(json.loads(sys.argv[4]))
json.dump(site, open(sys.argv[2], "w"), indent=1)
PY
    # The sim's recordings run from 0 to the scenario's duration: the tracks are reported to
    # there, as the node replay that made the DOAs would.
    audio_end_s=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["duration_s"])' \
      "$dir/scenario.json")
    "$binary" replay "$site" --doa-in "$doas" --audio-end-s "$audio_end_s" \
      --tracks-out "$dir/tracks-$likelihood$variant.jsonl" 2>"$dir/replay-$likelihood$variant.log"
    "$binary" eval --truth "$dir/truth.json" --tracks "$dir/tracks-$likelihood$variant.jsonl" \
      --json "$dir/eval-$likelihood$variant.json" >/dev/null
    python3 - "$dir/eval-$likelihood$variant.json" "$seed" "$likelihood" <<'PY'
import json, sys
report = json.load(open(sys.argv[1]))
drones = "; ".join(f'{s["id"]} {100 * s["coverage"]:.1f} % / {s["position"]["rmse_3d_m"]:.2f} m'
                   for s in report["sources"])
switches = sum(s["id_switches"] for s in report["sources"])
print(f'| {sys.argv[2]} | {sys.argv[3]} | {drones} | {switches} | '
      f'{report["non_drone_as_drone_time_s"]:.1f} s | {100 * report["false_track_fraction"]:.2f} % | '
      f'{report["non_drone_zone_entries"]} |')
PY
  done
done
