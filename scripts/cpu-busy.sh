#!/usr/bin/env bash
# How busy the machine's cores are, all of them together, every INTERVAL_S seconds (default 5):
# one line "HH:MM:SS PERCENT" per interval from /proc/stat (busy = every jiffy but idle and
# iowait), until stopped; on INT or TERM a last line gives the mean and how many intervals read
# under 90 %. The "% busy" figures of docs/ci.md come from it, run beside a CI run:
#   bash scripts/cpu-busy.sh > busy.log & sampler=$!; CI=true bash .ci/run; kill $sampler
set -euo pipefail
interval=${1:-5}
samples=0
busy_sum=0
under_90=0
summary() {
  if ((samples > 0)); then
    echo "mean $((busy_sum / samples)) % busy over $samples samples, $under_90 under 90 %"
  fi
  exit 0
}
trap summary INT TERM
read -r -a previous < <(head -1 /proc/stat)
while true; do
  sleep "$interval" &
  wait $! || true
  read -r -a current < <(head -1 /proc/stat)
  # Fields after "cpu": user nice system idle iowait irq softirq steal.
  idle=$(((current[4] + current[5]) - (previous[4] + previous[5])))
  total=0
  for field in 1 2 3 4 5 6 7 8; do total=$((total + current[field] - previous[field])); done
  if ((total > 0)); then
    busy=$((100 * (total - idle) / total))
    echo "$(date +%T) $busy"
    samples=$((samples + 1))
    busy_sum=$((busy_sum + busy))
    ((busy < 90)) && under_90=$((under_90 + 1))
  fi
  previous=("${current[@]}")
done
