#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Installs the Debian 12 packages cleanmap needs that are missing (apt-get; sudo when not root).
# `install-deps.sh sanitize` adds clang and its sanitizer runtimes (`make test`'s sanitizer build);
# `install-deps.sh fuzz` the same for `make fuzz` (libFuzzer is in the same runtime package).
set -euo pipefail
PACKAGES=(
  build-essential cmake pkg-config
  libmrpt-dev mrpt-apps mrpt-common
  liboctomap-dev libopencv-dev libeigen3-dev nlohmann-json3-dev libdeflate-dev
  libgtest-dev libbenchmark-dev
  clang-format-14  # pinned: `make format` and the style.format test use this exact version
)
if [[ "${1:-}" == "sanitize" || "${1:-}" == "fuzz" ]]; then
  PACKAGES+=(clang-14 libclang-rt-14-dev)
fi
missing=()
for p in "${PACKAGES[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done
if [[ ${#missing[@]} -eq 0 ]]; then
  echo "deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi
SUDO=""
if [[ $(id -u) -ne 0 ]]; then
  command -v sudo >/dev/null || { echo "deps: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  SUDO="sudo"
fi
echo "deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
