#!/usr/bin/env bash
# Installs the Debian 12 packages irfarm builds, tests and runs with, then (best effort) Intel Open
# Image Denoise 2 for `--denoise`. Idempotent: when everything is already installed it changes
# nothing and touches no network.
set -euo pipefail
packages=(
  cmake ninja-build g++ pkg-config
  libembree-dev libtbb-dev libopenexr-dev libpugixml-dev libstb-dev libnanoflann-dev
  libspdlog-dev libcli11-dev nlohmann-json3-dev zlib1g-dev libgtest-dev libgmock-dev libbenchmark-dev
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc
  libhiredis-dev redis-server python3-yaml
  libcpp-httplib-dev python3-prometheus-client curl
  chromium chromium-driver python3-selenium
  openssl
  python3 python3-pip  # python3-pip: fetches the Open Image Denoise wheel below
  clang libclang-rt-14-dev  # .ci/fuzz only: libFuzzer and the sanitizer runtimes for clang
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
if ((${#missing[@]} > 0)); then
  echo "installing: ${missing[*]}" >&2
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends \
    "${missing[@]}"
fi

# Open Image Denoise 2.5.1 (CPU), for `irfarm render --denoise`. Debian 12 has no package; the
# official prebuilt libraries ship in the `pyoidn` wheel on PyPI. Its CPU part (libOpenImageDenoise,
# core, device_cpu, its libtbb, the oidnDenoise tool: 58 MB of the wheel's 171 MB) is unpacked into
# $IRFARM_OIDN_DIR (default /opt/irfarm/oidn), where irfarm looks for it at run time. Best effort:
# irfarm builds and its tests pass without it; `--denoise` then says it is unavailable.
oidn_dir="${IRFARM_OIDN_DIR:-/opt/irfarm/oidn}"
install_oidn() {
  local tmp
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' RETURN
  python3 -m pip download -q --no-deps --only-binary=:all: --platform manylinux2014_x86_64 \
    -d "$tmp" "pyoidn==2.5.1.0" || return 1
  python3 - "$tmp"/pyoidn-*.whl "$tmp/x" <<'PY' || return 1
import sys, zipfile
keep = ("lib/libOpenImageDenoise.so.2", "lib/libOpenImageDenoise_core.so.2", "lib/libtbb.so.12",
        "lib/libOpenImageDenoise_device_cpu.so.2", "bin/oidnDenoise")
with zipfile.ZipFile(sys.argv[1]) as z:
    for name in z.namelist():
        rel = name.split("pyoidn/oidn/", 1)[-1]
        if name.startswith("pyoidn/oidn/") and any(rel.startswith(k) for k in keep):
            z.extract(name, sys.argv[2])
PY
  $SUDO mkdir -p "$oidn_dir"
  $SUDO cp -r "$tmp/x/pyoidn/oidn/lib" "$tmp/x/pyoidn/oidn/bin" "$oidn_dir/"
  $SUDO chmod -R a+rX "$oidn_dir"
  $SUDO chmod a+x "$oidn_dir"/bin/oidnDenoise
}
if [[ ! -e "$oidn_dir/lib/libOpenImageDenoise.so.2" ]]; then
  echo "installing Open Image Denoise 2.5.1 into $oidn_dir (from the pyoidn wheel)" >&2
  install_oidn || echo "warning: Open Image Denoise not installed (needs python3 -m pip and" \
    "network); irfarm works without it, --denoise will say it is unavailable" >&2
fi
