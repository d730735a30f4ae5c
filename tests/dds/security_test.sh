#!/usr/bin/env bash
# DDS Security end to end (issue 18), with the real binary and the site PKI made by
# scripts/site-pki.sh, on loopback in its own domain:
#  - nodes N1 and N2 with their identities feed a secure fusion: both are seen alive, tracks come;
#  - an N3 node without security, and an N3 node whose identity comes from another CA, run at
#    the same time: the fusion never hears of N3 (the first gets no discovery, the second fails
#    authentication);
#  - N1's identity trying to publish as array N2 (its partition) is refused at once, as is N1's
#    identity trying to subscribe to Alert;
#  - the capture of the loopback traffic (when tcpdump is present) holds no plaintext sample:
#    the array id strings of the DOAs are never seen in the clear.
# usage: security_test.sh DRONETRACK_BINARY SOURCE_DIR WORK_DIR
set -euo pipefail
bin="$1"; src="$2"; work="$3"
domain=147
rm -rf "$work"; mkdir -p "$work"
export CYCLONEDDS_URI="file://$src/config/cyclonedds-loopback.xml"
fail() { echo "security test: FAIL: $*" >&2; exit 1; }
pids=()
cleanup() { for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT

"$bin" sim "$src/tests/dds/perimeter-short.json" --out "$work/scene" 2> "$work/sim.log" \
  || fail "sim: $(tail -1 "$work/sim.log")"
bash "$src/scripts/site-pki.sh" "$work/pki" --nodes N1,N2,N3 --subscribers alert --domain "$domain" \
  2> "$work/pki.log" || fail "site-pki: $(tail -1 "$work/pki.log")"
bash "$src/scripts/site-pki.sh" "$work/rogue" --nodes N3 --domain "$domain" 2> "$work/rogue.log" \
  || fail "site-pki (rogue): $(tail -1 "$work/rogue.log")"
# The same site three ways: secure with the site's PKI, secure with the rogue CA, plain.
with_security() {  # DIR OUT
  sed "0,/{/s||{\"dds\": {\"domain_id\": $domain, \"security\": {\"directory\": \"$1\"}},|" \
    "$work/scene/site.json" > "$2"
}
with_security "$work/pki" "$work/scene/secure.json"
with_security "$work/rogue" "$work/scene/rogue.json"
grep -q '"security"' "$work/scene/secure.json" || fail "could not add dds.security to the site"

# Refusals first (each exits at once): a node's identity may neither write another array's
# partition nor read alerts.
if "$bin" node "$work/scene/secure.json" --array N2 --identity N1 --realtime --domain "$domain" \
    > /dev/null 2> "$work/impostor.log"; then
  fail "N1's identity published as N2"
fi
grep -q "Not Allowed By Security" "$work/impostor.log" || fail "impostor node: $(tail -1 "$work/impostor.log")"
if "$bin" alert "$work/scene/secure.json" --identity N1 --duration 2 --domain "$domain" \
    > /dev/null 2> "$work/reader.log"; then
  fail "N1's identity subscribed to Alert"
fi
grep -q "Not Allowed By Security" "$work/reader.log" || fail "unpermitted reader: $(tail -1 "$work/reader.log")"

run_fusion() {  # NAME DURATION: a secure fusion in the background
  "$bin" fusion "$work/scene/secure.json" --duration "$2" --domain "$domain" \
    --tracks-out "$work/$1-tracks.jsonl" 2> "$work/$1-fusion.log" &
  fusion=$!
  pids+=($fusion)
  sleep 1
  epoch=$(( $(date +%s) + 2 ))
}
node() {  # NAME SITE ARRAY: a node in step with the others
  "$bin" node "$2" --array "$3" --realtime --epoch "$epoch" --domain "$domain" 2> "$work/$1.log" &
  pids+=($!)
}

# Phase 1: the authenticated nodes alone, the loopback traffic captured where possible.
capture=""
if command -v tcpdump > /dev/null && [[ "$(id -u)" == 0 ]]; then
  capture="$work/loopback.pcap"
  # Only this domain's ports (Cyclone: 7400 + 250 x domain, then up to ~75 per participant index),
  # so another test's plain DDS traffic on the machine cannot be mistaken for ours.
  port=$((7400 + 250 * domain))
  tcpdump -i lo -w "$capture" -U "udp and portrange $port-$((port + 249))" 2> /dev/null &
  tcpdump_pid=$!
  pids+=($tcpdump_pid)
  sleep 0.5
fi
run_fusion secure 18
node node-N1 "$work/scene/secure.json" N1
node node-N2 "$work/scene/secure.json" N2
wait "$fusion" || fail "fusion exited with an error: $(tail -1 "$work/secure-fusion.log")"
grep -q "array N1 alive" "$work/secure-fusion.log" \
  || fail "the fusion never heard N1: $(tail -3 "$work/secure-fusion.log")"
grep -q "array N2 alive" "$work/secure-fusion.log" || fail "the fusion never heard N2"
grep -q '"status": *"confirmed"' "$work/secure-tracks.jsonl" \
  || fail "no confirmed track from the authenticated nodes"
if [[ -n "$capture" ]]; then
  kill "$tcpdump_pid" 2> /dev/null || true
  sleep 0.3
  [[ -s "$capture" ]] || fail "the loopback capture is empty"
  # Discovery announces each identity's subject name in the clear (that shows the capture sees
  # payloads); the samples, whose NodeStatus carries the software version, must never be.
  grep -a -q -F "dronetrack site" "$capture" || fail "the capture holds no readable payload at all"
  # -F: a fixed string (as a regex its dots would match any byte of the ciphertext).
  if grep -a -q -F "@DRONETRACK_VERSION@" "$capture"; then fail "plaintext sample payloads on the wire"; fi
  echo "security test: loopback capture of $(stat -c %s "$capture") bytes: no plaintext sample"
else
  echo "security test: no tcpdump (or not root): the plaintext check was skipped"
fi

# Phase 2: beside an authenticated N1, an N3 without security and an N3 from another CA.
run_fusion intruders 12
node intruder-N1 "$work/scene/secure.json" N1
node intruder-N3-plain "$work/scene/site.json" N3
node intruder-N3-rogue "$work/scene/rogue.json" N3
wait "$fusion" || fail "fusion exited with an error: $(tail -1 "$work/intruders-fusion.log")"
grep -q "array N1 alive" "$work/intruders-fusion.log" || fail "phase 2: the fusion never heard N1"
if grep -q "array N3" "$work/intruders-fusion.log"; then
  fail "the fusion heard an unauthenticated N3: $(grep "array N3" "$work/intruders-fusion.log" | head -1)"
fi
echo "security test: PASS ($(grep -c . "$work/secure-tracks.jsonl") track lines from N1+N2; N3 without a certificate and N3 from another CA unheard; impostor and unpermitted reader refused)"
