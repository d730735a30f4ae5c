#!/usr/bin/env bash
# Whole-process cost of a DOA-only replay of a 60 s two-array scene against the bare FFT kernel
# over the same frames, start-up included, and the replay's time to its first frame (issue 21).
#   bench/replay_cost.sh [runs]     (default 3; needs build/release's dronetrack and doa_bench)
# Prints per run: process wall and CPU, the kernel's CPU over the same frames (doa_bench's
# BM_FftCrossSpectrumKernel, median of 5, times the frames the replay analysed), the ratio
# process CPU / kernel CPU, and the time from process start to the first analysed frame.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
runs="${1:-3}"
build=build/release
scene=config/scenarios/seed002-rectangle.json # 60 s, two 4-mic arrays, 48 kHz as doa_bench
work="$build/replay_cost"
for tool in "$build/dronetrack" "$build/bench/doa_bench"; do
  [[ -x "$tool" ]] || { echo "replay_cost: $tool missing (cmake --build --preset release)" >&2; exit 2; }
done
if [[ ! -f "$work/site.json" ]]; then
  "$build/dronetrack" --log-level warn sim "$scene" --out "$work" >/dev/null
fi

kernel_us=$("$build/bench/doa_bench" --benchmark_filter='^BM_FftCrossSpectrumKernel$' \
  --benchmark_repetitions=5 --benchmark_report_aggregates_only=true 2>/dev/null |
  sed 's/\x1b\[[0-9;]*m//g' | awk '$1 == "BM_FftCrossSpectrumKernel_median" { print $4 }')
echo "FFT + cross-spectrum kernel: ${kernel_us} us CPU per frame (doa_bench, median of 5)"

for ((run = 1; run <= runs; ++run)); do
  log="$work/replay-$run.log"
  /usr/bin/time -f 'process %e %U %S' "$build/dronetrack" replay "$work/site.json" \
    --doa-out "$work/doas.jsonl" 2>"$log"
  awk -v kernel_us="$kernel_us" -v run="$run" '
    /first frame analysed/ {
      for (i = 1; i <= NF; ++i) if ($i == "analysed") first = $(i + 1)
      first_cpu = $(NF - 2)
    }
    /frames analysed/ { for (i = 1; i <= NF; ++i) if ($i == "frames") frames += $(i - 1) }
    $1 == "process" { wall = $2; cpu = $3 + $4 }
    END {
      kernel_s = frames * kernel_us * 1e-6
      printf "run %d: process %.2f s wall, %.2f s CPU; kernel over the same %d frames %.2f s CPU;" \
             " process / kernel %.2f; first frame %.3f s after start (%.3f s CPU)\n",
             run, wall, cpu, frames, kernel_s, cpu / kernel_s, first, first_cpu
    }' "$log"
done
