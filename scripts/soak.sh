#!/usr/bin/env bash
# Soak: a looping 14 s perimeter recording through three `node --realtime --loop` processes and
# a `fusion` over DDS on loopback, for DURATION_S seconds, sampling each process's RSS and CPU
# and the fusion's track output every INTERVAL_S (issue 18). Fails on drift:
#  - a process died, or the fusion exited with an error;
#  - RSS grew by more than max(8 MB, 10 %) from the first sample after warm-up to the last;
#  - a process used more than 1.5x the CPU in the last interval than in the first full one;
#  - an interval (of at least one 14 s pass) without new confirmed track lines.
# usage: scripts/soak.sh DRONETRACK_BINARY DURATION_S [INTERVAL_S=60] [WORK_DIR]
set -euo pipefail
bin="$1"; duration="$2"; interval="${3:-60}"; here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
work="${4:-$(mktemp -d /tmp/dronetrack-soak-XXXXXX)}"
domain=149
[[ "$duration" =~ ^[0-9]+$ && "$interval" =~ ^[0-9]+$ && "$interval" -ge 15 ]] \
  || { echo "soak: DURATION_S and INTERVAL_S (>= 15, one recording pass) are whole seconds" >&2; exit 2; }
(( duration >= 2 * interval )) || { echo "soak: DURATION_S must be at least two intervals" >&2; exit 2; }
mkdir -p "$work"
rm -f "$work/tracks.jsonl"  # the fusion appends: a reused work dir would count old tracks
export CYCLONEDDS_URI="file://$here/config/cyclonedds-loopback.xml"
fail() { echo "soak: FAIL: $*" >&2; exit 1; }
pids=()
trap 'for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done; wait 2>/dev/null || true' EXIT

"$bin" sim "$here/tests/dds/perimeter-short.json" --out "$work/scene" > /dev/null 2> "$work/sim.log" \
  || fail "sim: $(tail -1 "$work/sim.log")"
"$bin" fusion "$work/scene/site.json" --domain "$domain" --duration $((duration + 3)) \
  --tracks-out "$work/tracks.jsonl" 2> "$work/fusion.log" &
fusion=$!; pids+=($fusion)
names=(fusion); sleep 1
epoch=$(( $(date +%s) + 1 ))
for id in N1 N2 N3; do
  "$bin" node "$work/scene/site.json" --array "$id" --realtime --loop --epoch "$epoch" \
    --domain "$domain" 2> "$work/node-$id.log" &
  pids+=($!); names+=("$id")
done

rss_kb() { awk '/^VmRSS/ {print $2}' "/proc/$1/status" 2>/dev/null || echo 0; }
cpu_ticks() { awk '{print $14 + $15}' "/proc/$1/stat" 2>/dev/null || echo 0; }
confirmed() { grep -c '"status": *"confirmed"' "$work/tracks.jsonl" 2>/dev/null || echo 0; }
hz=$(getconf CLK_TCK)
printf "%8s" "t_s"; for name in "${names[@]}"; do printf " %10s %9s" "$name.rss_MB" "cpu_%"; done
printf " %10s\n" "confirmed"
declare -a first_rss last_rss first_cpu last_cpu previous_ticks
for i in "${!pids[@]}"; do previous_ticks[$i]=$(cpu_ticks "${pids[$i]}"); done
previous_confirmed=0; quiet_intervals=0; samples=0
for (( t = interval; t <= duration; t += interval )); do
  sleep "$interval"
  printf "%8d" "$t"
  for i in "${!pids[@]}"; do
    pid="${pids[$i]}"
    kill -0 "$pid" 2> /dev/null || fail "${names[$i]} died at ~$t s: $(tail -1 "$work/$([[ $i == 0 ]] && echo fusion || echo "node-${names[$i]}").log")"
    rss=$(rss_kb "$pid"); ticks=$(cpu_ticks "$pid")
    cpu=$(( (ticks - previous_ticks[i]) * 100 / (hz * interval) )); previous_ticks[$i]=$ticks
    if (( samples == 0 )); then first_rss[$i]=$rss; first_cpu[$i]=$cpu; fi
    last_rss[$i]=$rss; last_cpu[$i]=$cpu
    printf " %10.1f %9d" "$(awk -v kb="$rss" 'BEGIN { print kb / 1024 }')" "$cpu"
  done
  now_confirmed=$(confirmed)
  printf " %10d\n" "$now_confirmed"
  (( now_confirmed > previous_confirmed )) || quiet_intervals=$((quiet_intervals + 1))
  previous_confirmed=$now_confirmed; samples=$((samples + 1))
done
wait "$fusion" || fail "fusion exited with an error: $(tail -1 "$work/fusion.log")"
for i in "${!pids[@]}"; do
  growth=$(( last_rss[i] - first_rss[i] ))
  allowed=$(( first_rss[i] / 10 > 8192 ? first_rss[i] / 10 : 8192 ))
  (( growth <= allowed )) || fail "${names[$i]} RSS grew by $((growth / 1024)) MB (allowed $((allowed / 1024)) MB)"
  (( last_cpu[i] * 2 <= first_cpu[i] * 3 + 2 )) \
    || fail "${names[$i]} CPU rose from ${first_cpu[$i]} % to ${last_cpu[$i]} %"
done
(( quiet_intervals == 0 )) || fail "$quiet_intervals interval(s) without new confirmed tracks"
echo "soak: PASS: $duration s, ${#pids[@]} processes, RSS and CPU flat, confirmed tracks in every interval ($(grep 'DOAs received' "$work/fusion.log" | sed 's/.*fusion: //'))"
