#!/usr/bin/env bash
# Soak: a looping 14 s perimeter recording through three `node --realtime --loop` processes and
# a `fusion` over DDS on loopback, for DURATION_S seconds, sampling each process's RSS and CPU
# and the fusion's track output every INTERVAL_S (issue 18). Fails on drift:
#  - a process died, or the fusion exited with an error;
#  - private anonymous memory (RssAnon: heap, stacks; what a leak grows) grew, from the sample
#    ending the warm-up to the last, by more than SOAK_MAX_DRIFT_KB (default max(8 MB, 10 % of
#    RSS): loose enough for the short CI run's allocator noise). VmRSS is printed too; it also
#    counts mapped pages of the binary and libraries, which the page cache brings and takes;
#  - a process's CPU rate rose: over the second half of the post-warm-up samples it used more
#    than 1.5x its rate over the first half plus 2 % of a core. Rates are whole CPU seconds
#    over many intervals, not one interval's whole-percent sample: a node costs 1-3 % of a core,
#    where one interval's scheduling noise under a loaded CI doubles the figure; a leak that
#    costs CPU (a list that grows and is walked) keeps rising and is caught all the same;
#  - an interval (of at least one 14 s pass) without new confirmed track lines;
#  - counters: the fusion received more DOAs than the nodes published (duplicated), fewer by
#    more than 0.1 % (lost), the engine saw a duplicate DOA, or a track id came back after
#    it had ended (ids are never reused: each new id is above every earlier one, and an id's
#    lines have no gap of more than 5 s).
# Nodes are stopped first (SIGTERM: each logs what it published), then the fusion, so every
# published DOA had its chance to arrive.
# usage: [SOAK_DOMAIN=N] [SOAK_WARMUP_S=S] [SOAK_MAX_DRIFT_KB=K] \
#        scripts/soak.sh DRONETRACK_BINARY DURATION_S [INTERVAL_S=60] [WORK_DIR]
# SOAK_DOMAIN: the DDS domain (default 149; no test uses it, so a soak can run beside the
# tests). SOAK_WARMUP_S: samples before this are warm-up (default: a sixth of the run, at least
# one interval): the drift is measured from the sample at its end.
set -euo pipefail
bin="$1"; duration="$2"; interval="${3:-60}"; here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
work="${4:-$(mktemp -d /tmp/dronetrack-soak-XXXXXX)}"
domain="${SOAK_DOMAIN:-149}"
warmup="${SOAK_WARMUP_S:-$(( $2 / 6 ))}"
[[ "$duration" =~ ^[0-9]+$ && "$interval" =~ ^[0-9]+$ && "$interval" -ge 15 ]] \
  || { echo "soak: DURATION_S and INTERVAL_S (>= 15, one recording pass) are whole seconds" >&2; exit 2; }
(( duration >= 2 * interval )) || { echo "soak: DURATION_S must be at least two intervals" >&2; exit 2; }
[[ "$domain" =~ ^[0-9]+$ && "$domain" -le 232 && "$warmup" =~ ^[0-9]+$ && "$warmup" -lt "$duration" ]] \
  || { echo "soak: SOAK_DOMAIN is 0..232, SOAK_WARMUP_S whole seconds below DURATION_S" >&2; exit 2; }
(( warmup >= interval )) || warmup=$interval
mkdir -p "$work"
rm -f "$work/tracks.jsonl"  # the fusion appends: a reused work dir would count old tracks
export CYCLONEDDS_URI="file://$here/config/cyclonedds-loopback.xml"
fail() { echo "soak: FAIL: $*" >&2; exit 1; }
pids=()
trap 'for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done; wait 2>/dev/null || true' EXIT

"$bin" sim "$here/tests/dds/perimeter-short.json" --out "$work/scene" > /dev/null 2> "$work/sim.log" \
  || fail "sim: $(tail -1 "$work/sim.log")"
"$bin" fusion "$work/scene/site.json" --domain "$domain" --duration $((duration + 120)) \
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
# Private anonymous memory (heap, stacks): what a leak grows. VmRSS also counts the pages of the
# binary and shared libraries mapped in, which come and go with the machine's page cache.
anon_kb() { awk '/^RssAnon/ {print $2}' "/proc/$1/status" 2>/dev/null || echo 0; }
cpu_ticks() { awk '{print $14 + $15}' "/proc/$1/stat" 2>/dev/null || echo 0; }
confirmed() {  # grep -c prints 0 and fails on no match
  local n; n=$(grep -c '"status": *"confirmed"' "$work/tracks.jsonl" 2> /dev/null || true); echo "${n:-0}"
}
hz=$(getconf CLK_TCK)
printf "%8s" "t_s"
for name in "${names[@]}"; do printf " %10s %11s %5s" "$name.rss_MB" "anon_MB" "cpu_%"; done
printf " %10s\n" "confirmed"
declare -a first_rss last_rss first_anon last_anon previous_ticks
declare -A ticks_at  # "process,sample" -> the process's cumulative CPU ticks at that sample
declare -a sample_t
for i in "${!pids[@]}"; do previous_ticks[$i]=$(cpu_ticks "${pids[$i]}"); done
previous_confirmed=0; quiet_intervals=0; samples=0
for (( t = interval; t <= duration; t += interval )); do
  sleep "$interval"
  printf "%8d" "$t"
  for i in "${!pids[@]}"; do
    pid="${pids[$i]}"
    kill -0 "$pid" 2> /dev/null || fail "${names[$i]} died at ~$t s: $(tail -1 "$work/$([[ $i == 0 ]] && echo fusion || echo "node-${names[$i]}").log")"
    rss=$(rss_kb "$pid"); anon=$(anon_kb "$pid"); ticks=$(cpu_ticks "$pid")
    cpu=$(( (ticks - previous_ticks[i]) * 100 / (hz * interval) )); previous_ticks[$i]=$ticks
    ticks_at["$i,$samples"]=$ticks
    if (( t >= warmup )) && [[ -z "${first_rss[$i]:-}" ]]; then
      first_rss[$i]=$rss; first_anon[$i]=$anon; baseline_t=$t; baseline_sample=$samples
    fi
    last_rss[$i]=$rss; last_anon[$i]=$anon
    printf " %10.1f %11.2f %5d" "$(awk -v kb="$rss" 'BEGIN { print kb / 1024 }')" \
      "$(awk -v kb="$anon" 'BEGIN { print kb / 1024 }')" "$cpu"
  done
  now_confirmed=$(confirmed)
  printf " %10d\n" "$now_confirmed"
  (( now_confirmed > previous_confirmed )) || quiet_intervals=$((quiet_intervals + 1))
  sample_t[$samples]=$t; previous_confirmed=$now_confirmed; samples=$((samples + 1))
done
# Nodes first: each logs "N DOAs published" on SIGTERM; then the fusion, once they are gone.
for i in "${!pids[@]}"; do (( i == 0 )) || kill -TERM "${pids[$i]}"; done
for i in "${!pids[@]}"; do (( i == 0 )) || wait "${pids[$i]}" || true; done
sleep 1
kill -TERM "$fusion"
code=0; wait "$fusion" || code=$?
(( code == 0 || code == 143 )) || fail "fusion exited with $code: $(tail -1 "$work/fusion.log")"
# Every figure is printed before the verdict: a failed check does not hide the others.
problems=()
problem() { echo "soak: $*" >&2; problems+=("$*;"); }
drift_line="drift over the last $((t - interval - baseline_t)) s (after $baseline_t s warm-up), RSS / anonymous:"
for i in "${!pids[@]}"; do
  drift_line+=" ${names[$i]} $(printf '%+d / %+d' $(( last_rss[i] - first_rss[i] )) $(( last_anon[i] - first_anon[i] ))) kB"
done
echo "soak: $drift_line"
for i in "${!pids[@]}"; do
  growth=$(( last_anon[i] - first_anon[i] ))
  allowed=${SOAK_MAX_DRIFT_KB:-$(( first_rss[i] / 10 > 8192 ? first_rss[i] / 10 : 8192 ))}
  (( growth <= allowed )) || problem "${names[$i]} anonymous memory grew by $growth kB (allowed $allowed kB)"
done
# CPU rate (per mille of a core) over the two halves of the samples after the warm-up.
last_sample=$((samples - 1)); middle_sample=$(( (baseline_sample + last_sample + 1) / 2 ))
cpu_rate() {  # process first_sample last_sample -> per mille of one core between them
  local ticks=$(( ticks_at["$1,$3"] - ticks_at["$1,$2"] )) seconds=$(( sample_t[$3] - sample_t[$2] ))
  echo $(( ticks * 1000 / (hz * seconds) ))
}
cpu_line="CPU per mille of a core, ${sample_t[$baseline_sample]}-${sample_t[$middle_sample]} s / ${sample_t[$middle_sample]}-${sample_t[$last_sample]} s:"
(( last_sample - baseline_sample >= 2 )) || problem "too few samples after the warm-up to compare CPU rates (run longer)"
for i in "${!pids[@]}"; do
  (( last_sample - baseline_sample >= 2 )) || break
  early=$(cpu_rate "$i" "$baseline_sample" "$middle_sample")
  late=$(cpu_rate "$i" "$middle_sample" "$last_sample")
  cpu_line+=" ${names[$i]} $early / $late"
  (( late * 2 <= early * 3 + 40 )) \
    || problem "${names[$i]} CPU rose from $early to $late per mille of a core (allowed 1.5x + 20)"
done
echo "soak: $cpu_line"
(( quiet_intervals == 0 )) || problem "$quiet_intervals interval(s) without new confirmed tracks"

# Counters: published per node (its exit line) against what the fusion received.
published=0; per_node=""
for id in N1 N2 N3; do
  n=$(sed -n 's/.* \([0-9]\+\) DOAs published.*/\1/p' "$work/node-$id.log" | tail -1)
  [[ -n "$n" ]] || fail "node $id logged no published count: $(tail -1 "$work/node-$id.log")"
  published=$((published + n)); per_node+=" $id $n"
done
summary=$(grep 'DOAs received' "$work/fusion.log" | tail -1 | sed 's/.*fusion: //')
received=$(sed -n 's/^\([0-9]\+\) DOAs received.*/\1/p' <<< "$summary")
duplicate=$(sed -n 's/.*duplicate \([0-9]\+\)).*/\1/p' <<< "$summary")
[[ -n "$received" && -n "$duplicate" ]] || fail "no counters in the fusion's log: $summary"
lost=$((published - received))
echo "soak: DOAs published:$per_node (total $published); fusion received $received (lost $lost), engine duplicates $duplicate"
(( received <= published )) || problem "the fusion received $((received - published)) DOAs more than were published"
(( lost * 1000 <= published )) || problem "$lost of $published DOAs lost (tolerance 0.1 %)"
(( duplicate == 0 )) || problem "$duplicate duplicate DOAs reached the engine"
reused=$(awk '
  match($0, /"t": *[-0-9.e+]+/) { t = substr($0, RSTART, RLENGTH); sub(/"t": */, "", t) }
  match($0, /"id": *[0-9]+/) {
    id = substr($0, RSTART, RLENGTH); sub(/"id": */, "", id); id += 0
    if (!(id in last)) { if (id <= highest) bad++; if (id > highest) highest = id; ids++ }
    else if (t - last[id] > 5) bad++
    last[id] = t
  }
  END { printf "%d %d %d\n", bad + 0, ids + 0, highest + 0 }' "$work/tracks.jsonl")
read -r reuses track_ids highest_id <<< "$reused"
echo "soak: $track_ids track ids (highest $highest_id), $reuses reused"
(( reuses == 0 )) || problem "$reuses track id(s) came back after ending or out of order"
(( ${#problems[@]} == 0 )) || fail "${problems[*]}"
echo "soak: PASS: $duration s, ${#pids[@]} processes, RSS and CPU flat, confirmed tracks in every interval ($summary)"
