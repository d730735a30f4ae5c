#!/usr/bin/env bash
# Builds the libFuzzer harnesses (fuzz/README.md) with clang + ASan + UBSan into build/fuzz and
# runs each for a bounded time on its seed corpus and regression inputs. Exits non-zero on the
# first harness that finds a crash, leak, UB or timeout, naming the saved input.
#   scripts/fuzz.sh [SECONDS_PER_HARNESS] [HARNESS...]   (default 20 s each, all harnesses;
#                                                        0: build only)
# New inputs that reach new code go to build/fuzz/corpus/HARNESS (kept between runs, never
# committed); a crashing input is saved as build/fuzz/artifacts/HARNESS/crash-*.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
seconds="${1:-20}"
shift || true
all=(site_config scenario doa_lines recording dds_conversions http_request)
harnesses=("${@:-${all[@]}}")
# The harnesses build beside the ASan tests when the asan preset is configured (clang,
# DRONETRACK_FUZZ on: scripts/test.sh passes DRONETRACK_FUZZ_BUILD=build/asan, so CI compiles the
# sanitized code once); otherwise in a build of their own.
build="${DRONETRACK_FUZZ_BUILD:-build/fuzz}"

# Largest input worth trying per harness: a site config or scenario is a few kB, a DOA line
# < 1 kB, a request head < 8 kB; recordings need room for a header and a few frames.
max_len() {
  case "$1" in
    site_config | scenario) echo 8192 ;;
    doa_lines | http_request) echo 4096 ;;
    recording) echo 4096 ;;
    dds_conversions) echo 1024 ;;
  esac
}

echo "== fuzz: build (clang, ASan + UBSan + libFuzzer) in $build" >&2
# -O1 -gline-tables-only: as OSS-Fuzz builds, stack traces with lines. (-O0 compiles in ~60 % of
# the CPU time but runs Eigen and nlohmann-json 25-40x slower: 321 site-config and 65 DOA-line
# executions per second instead of ~9 k and ~2.7 k; not worth it even for CI's short runs.)
flags="-O1 -gline-tables-only"
if ! grep -qs '^DRONETRACK_FUZZ:BOOL=ON' "$build/CMakeCache.txt"; then
  CC=clang CXX=clang++ cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$flags" -DCMAKE_C_FLAGS_RELWITHDEBINFO="$flags" \
    -DDRONETRACK_FUZZ=ON -DDRONETRACK_BUILD_TESTS=OFF -DDRONETRACK_BUILD_BENCH=OFF >/dev/null
fi
targets=()
for harness in "${harnesses[@]}"; do targets+=("fuzz_$harness"); done
cmake --build "$build" -j"$(nproc)" --target "${targets[@]}"
((seconds > 0)) || exit 0  # 0: build only (libFuzzer would take 0 as "no limit")

# One harness: its run, then a line saying how it went; non-zero if it found something.
run_harness() {
  local harness="$1"
  local corpus="$build/corpus/$harness" artifacts="$build/artifacts/$harness"
  local log="$build/$harness.log"
  mkdir -p "$corpus" "$artifacts"
  local seeds=(fuzz/corpus/"$harness")
  [[ -d fuzz/regressions/$harness ]] && seeds+=(fuzz/regressions/"$harness")
  local options=(-max_total_time="$seconds" -max_len="$(max_len "$harness")" -timeout=10
                 -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$artifacts/")
  [[ -f fuzz/dict/$harness.dict ]] && options+=(-dict=fuzz/dict/"$harness".dict)
  if ! ASAN_OPTIONS=abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$build/fuzz/fuzz_$harness" "${options[@]}" "$corpus" "${seeds[@]}" >"$log" 2>&1; then
    tail -n 60 "$log" >&2
    echo "fuzz: $harness FAILED: input saved in $artifacts/ (log $log); fix the code, then add" \
      "the input to fuzz/regressions/$harness/" >&2
    return 1
  fi
  local runs rate
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")
  echo "fuzz: $harness: ${runs:-?} runs in ${seconds} s, ${rate:-?} exec/s, corpus $(ls "$corpus" | wc -l) inputs, no crash" >&2
}

# As many harnesses at once as there are cores: each is one process on one core, and
# -max_total_time counts wall time, so a shared core would halve its executions.
echo "== fuzz: ${#harnesses[@]} harnesses for ${seconds} s each, $(nproc) at a time" >&2
failed=0
running=0
for harness in "${harnesses[@]}"; do
  if ((running >= $(nproc))); then
    wait -n || failed=$((failed + 1))
    running=$((running - 1))
  fi
  run_harness "$harness" &
  running=$((running + 1))
done
while ((running > 0)); do
  wait -n || failed=$((failed + 1))
  running=$((running - 1))
done
# The closing line CI reads as a test count.
echo "fuzz: $((${#harnesses[@]} - failed)) passed, $failed failed"
((failed == 0))
