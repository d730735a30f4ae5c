#!/usr/bin/env bash
# Issue 17's table: the drone scenes with 0 / 10 / 30 % impulsive DOA outliers, each filter with
# each DOA likelihood: RMSE, coverage, id switches, tracks per drone (docs/fusion.md "Impulsive DOA
# errors"). Per scene: `sim` and one `replay --doa-out` (the DOAs), then for every cell
# `replay --doa-in DOAS --doa-outliers SHARE` on a copy of the site whose fusion section names the
# filter and likelihood, and `eval` against the truth. Prints one Markdown row per cell.
#
# Usage: scripts/outlier-table.sh [--work DIR] [--scenes "a b"] [--filters "ukf ekf"]
#                                 [--likelihoods "gaussian outlier_mixture"] [--shares "0 0.1 0.3"]
#                                 [--fusion '{"outlier_probability": 0.05}'] [--outlier-seeds "1 2"]
# Likelihood `outlier_mixture` is the fixed e (fusion.adaptive_outlier_probability false),
# `adaptive` the mixture with e estimated per array; a likelihood may carry more numeric fusion
# keys after a colon (`outlier_mixture:outlier_probability=0.05,gate_probability=0.99`); --fusion merges more fusion keys into each
# site (the row names the likelihood only: keep one --fusion per --work directory).
# Defaults: DIR build/outlier-table (kept: a second run reuses its scenes and DOAs), the scenes
# seed002-rectangle and perimeter-two-drones, filters ukf ukf_seed002 ekf particle, likelihoods
# gaussian outlier_mixture student_t, shares 0 0.1 0.3. Outliers: alpha 1.5, scale 5 deg, seed 1
# (replay's defaults; --outlier-seeds: one row per seed of the outliers' draw, `replay
# --doa-outlier-seed`, for the spread one draw hides). Needs build/release/dronetrack (or $DRONETRACK_BINARY) and python3.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
work=build/outlier-table
scenes="seed002-rectangle perimeter-two-drones"
filters="ukf ukf_seed002 ekf particle"
likelihoods="gaussian outlier_mixture student_t"
shares="0 0.1 0.3"
fusion="{}"
outlier_seeds="1"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --work) work="$2"; shift 2 ;;
    --scenes) scenes="$2"; shift 2 ;;
    --filters) filters="$2"; shift 2 ;;
    --likelihoods) likelihoods="$2"; shift 2 ;;
    --shares) shares="$2"; shift 2 ;;
    --fusion) fusion="$2"; shift 2 ;;
    --outlier-seeds) outlier_seeds="$2"; shift 2 ;;
    *) echo "outlier-table.sh: unknown argument '$1' (see the header for usage)" >&2; exit 2 ;;
  esac
done
binary=${DRONETRACK_BINARY:-$PWD/build/release/dronetrack}
[[ -x "$binary" ]] || { echo "outlier-table.sh: $binary not built" >&2; exit 1; }
mkdir -p "$work"

echo "| scene | filter | likelihood | outliers | RMSE all (per drone) m | coverage (per drone) | id switches | tracks per drone |"
echo "|---|---|---|---|---|---|---|---|"
for scene in $scenes; do
  dir=$work/$scene
  scenario=config/scenarios/$scene.json
  [[ -f "$scenario" ]] || { echo "outlier-table.sh: no scenario $scenario" >&2; exit 1; }
  if [[ ! -f "$dir/truth.json" ]]; then
    "$binary" sim "$scenario" --out "$dir" >/dev/null 2>"$work/$scene.sim.log"
  fi
  if [[ ! -f "$dir/doas.jsonl" ]]; then
    "$binary" replay "$dir/site.json" --doa-out "$dir/doas.jsonl" --tracks-out /dev/null \
      2>"$work/$scene.replay.log"
  fi
  for filter in $filters; do
    for likelihood in $likelihoods; do
      tag=${likelihood//[:=,]/_}
      site=$dir/site-$filter-$tag.json
      python3 - "$dir/site.json" "$site" "$filter" "$likelihood" "$fusion" <<'EOF'
import json, sys
site = json.load(open(sys.argv[1]))
kind, _, extra = sys.argv[4].partition(":")
adaptive = kind == "adaptive"
site.setdefault("fusion", {}).update({
    "filter": sys.argv[3], "likelihood": "outlier_mixture" if adaptive else kind,
    "adaptive_outlier_probability": adaptive})
for pair in filter(None, extra.split(",")):
    key, value = pair.split("=")
    site["fusion"][key] = float(value)
site["fusion"].update(json.loads(sys.argv[5]))
json.dump(site, open(sys.argv[2], "w"), indent=1)
EOF
      for share in $shares; do
      for seed in $outlier_seeds; do
        [[ "$share" == 0 && "$seed" != "${outlier_seeds%% *}" ]] && continue  # no draw to vary
        name=$filter-$tag-$share
        [[ "$seed" != 1 ]] && name=$name-seed$seed
        outliers=()
        [[ "$share" != 0 ]] && outliers=(--doa-outliers "$share" --doa-outlier-seed "$seed")
        "$binary" replay "$site" --doa-in "$dir/doas.jsonl" "${outliers[@]}" \
          --tracks-out "$dir/tracks-$name.jsonl" 2>"$dir/replay-$name.log"
        "$binary" eval --truth "$dir/truth.json" --tracks "$dir/tracks-$name.jsonl" \
          --json "$dir/eval-$name.json" >/dev/null
        label=$share
        [[ "$share" != 0 && "$outlier_seeds" != 1 ]] && label="$share seed $seed"
        python3 - "$dir/eval-$name.json" "$scene" "$filter" "$likelihood" "$label" <<'EOF'
import json, sys
report = json.load(open(sys.argv[1]))
scene, filter_, likelihood, label = sys.argv[2:6]
share, _, seed = label.partition(" seed ")
drones = report["sources"]  # the drones; other sources are under "others"
rmse = " / ".join(f'{s["position"]["rmse_3d_m"]:.3f}' for s in drones)
coverage = " / ".join(f'{100 * s["coverage"]:.2f}' for s in drones)
tracks = " / ".join(str(len(s["track_ids"])) for s in drones)
switches = sum(s["id_switches"] for s in drones)
seed = f" (seed {seed})" if seed else ""
print(f'| {scene} | {filter_} | {likelihood} | {100 * float(share):.0f} %{seed} | '
      f'{report["position"]["rmse_3d_m"]:.3f} ({rmse}) | {100 * report["coverage"]:.2f} % '
      f'({coverage}) | {switches} | {tracks} |')
EOF
      done
      done
    done
  done
done
