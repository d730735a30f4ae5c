#!/usr/bin/env bash
# The executable's read-only files come from beside its install prefix first (apps/data_paths.hpp):
# a copy of the binary in PREFIX/bin with PREFIX/share/dronetrack/scenarios/ defaults `demo` to
# that scenario; with the folder missing it falls back to the source tree's.
# usage: data_paths_test.sh DRONETRACK_BINARY SOURCE_DIR WORK_DIR
set -euo pipefail
bin="$1"; src="$2"; work="$3"
fail() { echo "data paths test: FAIL: $*" >&2; exit 1; }
rm -rf "$work"; mkdir -p "$work/prefix/bin"
cp "$bin" "$work/prefix/bin/dronetrack"
ln -s "$work/prefix/bin/dronetrack" "$work/link"  # a link elsewhere still finds its own prefix
"$work/link" demo --help | grep -qF "$src/config/scenarios/perimeter-two-drones.json" \
  || fail "without PREFIX/share/dronetrack, demo's default scenario is not the source tree's"
mkdir -p "$work/prefix/share/dronetrack/scenarios"
cp "$src/config/scenarios/perimeter-two-drones.json" "$work/prefix/share/dronetrack/scenarios/"
"$work/link" demo --help | grep -qF "$work/prefix/share/dronetrack/scenarios/perimeter-two-drones.json" \
  || fail "demo's default scenario is not PREFIX/share/dronetrack/scenarios/perimeter-two-drones.json"
echo "data paths test: PREFIX/share/dronetrack first, then the source tree"
