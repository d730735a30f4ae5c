#!/usr/bin/env python3
"""Where the node's frame goes, by pipeline stage, from a perf profile of doa_bench.

The shares docs/doa.md quotes ("Pipeline / kernel, earlier sessions", session 25). Record and
dump the call stacks, then group them:

    perf record --call-graph dwarf,16384 -F 2000 -o perf.data \\
      ./build/release/bench/doa_bench --simd-target=AVX2 \\
      --benchmark_filter='BM_NodePipeline/0$' --benchmark_min_time=2s
    perf script -i perf.data -F ip,sym > stacks.txt
    python3 scripts/perf-stage-shares.py stacks.txt [--within find_candidates]

A sample counts when its stack holds NodePipeline::process (the bench's set-up and the synthetic
audio do not). Its stage is the frame called by NodePipeline::Impl::analyse, or, outside
analyse, the frame called by NodePipeline::process (the framer, for one). --within STAGE splits
that stage's samples by the frame it calls in turn. Shares are of all counted samples.
"""
import argparse
import collections
import re
import sys

PROCESS = "dronetrack::doa::NodePipeline::process"
ANALYSE = "dronetrack::doa::NodePipeline::Impl::analyse"


def stacks(path):
    """Each sample's frames, leaf first, as symbol names (perf script -F ip,sym)."""
    frames = []
    with open(path, encoding="utf-8", errors="replace") as text:
        for line in text:
            line = line.strip()
            if not line:
                if frames:
                    yield frames
                frames = []
                continue
            parts = line.split(None, 1)
            frames.append(parts[1] if len(parts) > 1 else "[unknown]")
    if frames:
        yield frames


def short(symbol):
    """The function's name without namespaces, arguments or perf's '(inlined)' tag."""
    symbol = re.sub(r"\s*\(inlined\)$", "", symbol)
    symbol = re.sub(r"\(.*$", "", symbol)
    return symbol.rsplit("::", 1)[-1] or symbol


def callee_of(frames, caller):
    """The name of the frame `caller` called (the one just leafward of it), or None."""
    for index, frame in enumerate(frames):
        if frame.startswith(caller):
            return short(frames[index - 1]) if index > 0 else "(itself)"
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("stacks", help="output of perf script -F ip,sym")
    parser.add_argument("--within", help="split this stage by what it calls")
    options = parser.parse_args()
    counted = 0
    by_stage = collections.Counter()
    within = collections.Counter()
    for frames in stacks(options.stacks):
        if not any(frame.startswith(PROCESS) for frame in frames):
            continue
        counted += 1
        stage = callee_of(frames, ANALYSE)
        if stage is None:
            stage = callee_of(frames, PROCESS)
        by_stage[stage] += 1
        if options.within and stage == options.within:
            for index, frame in enumerate(frames):
                if short(frame) == options.within:
                    within[short(frames[index - 1]) if index > 0 else "(itself)"] += 1
                    break
    if counted == 0:
        sys.exit(f"perf-stage-shares: no sample in {options.stacks} holds {PROCESS}")
    print(f"{counted} samples inside NodePipeline::process")
    print("| stage | share of the frame |\n|---|---|")
    for stage, count in by_stage.most_common():
        print(f"| {stage} | {100.0 * count / counted:.1f} % |")
    if options.within:
        print(f"\n| {options.within} calls | share of the frame |\n|---|---|")
        for callee, count in within.most_common():
            print(f"| {callee} | {100.0 * count / counted:.1f} % |")


if __name__ == "__main__":
    main()
