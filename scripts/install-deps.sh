#!/usr/bin/env bash
# Installs what dronetrack needs from Debian 12 packages, by name. Idempotent and quick when
# everything is present (no apt-get update unless something is missing).
#   scripts/install-deps.sh          build + run dependencies
#   scripts/install-deps.sh --tests  also what the tests need (Chromium, playwright-core,
#                                    systemd-analyze for the package test, nftables)
#   scripts/install-deps.sh --arm64  also the arm64 cross-build of the core (scripts/arm64-test.sh):
#                                    Debian's cross compiler, qemu-user, multiarch arm64 libraries
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

packages=(
  build-essential cmake pkg-config git      # toolchain
  dpkg-dev file                             # the .deb's Depends (CPack: dpkg-shlibdeps, file)
  lld                                       # faster linker (cmake/BuildSpeed.cmake)
  libeigen3-dev                             # linear algebra of the DOA solver and filters
  libfftw3-dev                              # FFTs for GCC-PHAT
  libhwy-dev                                # portable SIMD kernels (Google Highway)
  libceres-dev                              # the site calibration's least squares (calib/)
  libsndfile1-dev                           # reading/writing multichannel recordings
  portaudio19-dev                           # live capture
  cyclonedds-dev cyclonedds-tools           # DDS transport + idlc
  nlohmann-json3-dev                        # JSON config and outputs
  libcpp-httplib-dev                        # HTTP API for the web page
  libssl-dev                                # HTTPS and the users file's PBKDF2 (OpenSSL)
  libcli11-dev                              # command line
  libgtest-dev libgmock-dev libbenchmark-dev # tests and benchmarks
)
if [[ "${1:-}" == "--tests" ]]; then
  packages+=(chromium clang-format openssl tcpdump)  # openssl: test certificates; tcpdump: DDS capture
  packages+=(nftables)  # dds.lossy_network: packet loss on loopback in a network namespace
  packages+=(clang libclang-rt-dev)  # scripts/fuzz.sh: clang 14 with libFuzzer + sanitizer runtimes
  packages+=(systemd curl)  # the package test: systemd-analyze verify on the units, GET the page
  command -v node >/dev/null 2>&1 || packages+=(nodejs)
  command -v npm >/dev/null 2>&1 || packages+=(npm)
fi
if [[ "${1:-}" == "--arm64" ]]; then
  # Eigen and nlohmann-json are header-only: the host's serve both builds. libhwy-dev is the
  # portable SIMD layer's library (issue 21), installed before that lands.
  packages+=(g++-aarch64-linux-gnu qemu-user libfftw3-dev:arm64 libsndfile1-dev:arm64
    libgtest-dev:arm64 libbenchmark-dev:arm64 libhwy-dev:arm64)
  dpkg --print-foreign-architectures | grep -qx arm64 || dpkg --add-architecture arm64
fi

# An unqualified name means the host's package; once arm64 is added (--arm64) dpkg-query would
# list both architectures' copies, so ask for the host's (arch-all packages take no qualifier).
native="$(dpkg --print-architecture)"
missing=()
for package in "${packages[@]}"; do
  query="$package"
  arch=$(dpkg-query -W -f='${Architecture}\n' "$package" 2>/dev/null | head -n 1 || true)
  [[ "$package" == *:* || -z "$arch" || "$arch" == all ]] || query="$package:$native"
  status=$(dpkg-query -W -f='${Status}' "$query" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$package")
done
if ((${#missing[@]})); then
  echo "install-deps: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# The browser test drives Debian's Chromium through playwright-core (no browser download).
if [[ "${1:-}" == "--tests" && -f "$here/web/test/package.json" ]]; then
  if [[ ! -d "$here/web/test/node_modules/playwright-core" ]]; then
    (cd "$here/web/test" && npm install --no-audit --no-fund --silent >/dev/null)
  fi
fi
