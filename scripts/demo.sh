#!/usr/bin/env bash
# The main job: install what is missing, build, run `dronetrack demo`.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release -j"$(nproc)"
exec ./build/release/dronetrack demo "$@"
