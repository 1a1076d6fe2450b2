#!/usr/bin/env bash
# Installs every Debian 12 package tagsfm needs to build, test and run.
# Idempotent: packages already installed are skipped, and apt is not touched
# at all when nothing is missing.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config git ccache ninja-build
  libopencv-dev libopencv-contrib-dev
  libpng-dev       # recorded frames written with a chosen PNG filter (capture/png_encoding.h)
  libeigen3-dev libceres-dev
  libapriltag-dev
  libv4l-dev libcamera-dev
  libspdlog-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev libyaml-cpp-dev nlohmann-json3-dev libcpp-httplib-dev
  gnuplot-nox
  libsystemd-dev   # sd_notify: the daemon under systemd (scripts/tagsfm.service)
  chromium         # the dashboard's browser test (tests/dashboard), headless
  qemu-system-x86 busybox-static cpio kmod v4l-utils   # the vivid capture test (scripts/vivid/)
  clang libclang-rt-14-dev   # scripts/fuzz.sh: libFuzzer and its sanitizers
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages already installed"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
