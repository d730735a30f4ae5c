#!/usr/bin/env bash
# The Debian package (issue 19): the release build, then CPack's DEB generator (cmake/
# DebianPackage.cmake). Writes build/release/dronetrack_<version>_<arch>.deb and prints its
# size and Depends. Installing it: docs/deployment.md, "The Debian package".
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/install-deps.sh  # dpkg-dev: dpkg-shlibdeps computes Depends
cmake --preset release >/dev/null
cmake --build --preset release -j"$(nproc)" --target package
version=$(sed -n 's/^project(dronetrack VERSION \([0-9.]*\).*/\1/p' CMakeLists.txt)
deb="build/release/dronetrack_${version}_$(dpkg --print-architecture).deb"
[[ -f "$deb" ]] || { echo "package-deb: $deb was not written" >&2; exit 1; }
echo "$deb: $(du -k "$deb" | cut -f1) KiB"
echo "Depends: $(dpkg-deb -f "$deb" Depends)"
