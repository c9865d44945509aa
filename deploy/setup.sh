#!/usr/bin/env bash
# Installs the Debian 12 packages irfarm builds, tests and runs with. Idempotent: when every
# package is already installed it changes nothing and touches no network.
set -euo pipefail
packages=(
  cmake ninja-build g++ pkg-config
  libembree-dev libtbb-dev libopenexr-dev libpugixml-dev libstb-dev
  libspdlog-dev libcli11-dev libgtest-dev libgmock-dev libbenchmark-dev
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc
  libhiredis-dev redis-server python3-yaml
  openssl
  python3
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]} == 0)); then
  exit 0
fi
echo "installing: ${missing[*]}" >&2
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
