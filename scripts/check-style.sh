#!/usr/bin/env bash
# Formatting (clang-format) and layering: the estimation core (doa/, fusion/, calib/) never
# includes an edge header (DDS, PortAudio, sndfile, HTTP, JSON, CLI) nor a header of an edge module.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
status=0
mapfile -t sources < <(git ls-files '*.cpp' '*.hpp' | grep -v '^web/')
if command -v clang-format >/dev/null 2>&1; then
  if ! clang-format --dry-run --Werror "${sources[@]}" 2>/tmp/dronetrack-format.log; then
    echo "check-style: files not clang-formatted (run: clang-format -i \$(git ls-files '*.cpp' '*.hpp')):" >&2
    grep -o '^[^:]*:' /tmp/dronetrack-format.log | sort -u >&2
    status=1
  fi
fi
forbidden='#include *[<"](dds/|portaudio|sndfile|httplib|nlohmann|CLI/|capture/|config/|sim/|dds_idl/|http_api/|apps/)'
if grep -nE "$forbidden" $(git ls-files 'doa/*' 'fusion/*' 'calib/*' | grep -E '\.(cpp|hpp)$'); then
  echo "check-style: the core (doa/, fusion/, calib/) includes an edge header (above)" >&2
  status=1
fi
exit $status
