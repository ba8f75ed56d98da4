#!/usr/bin/env bash
# Prepare a fresh Debian/Ubuntu machine for axisloop: system libraries, .venv/, torch, the package.
# Safe to run again: every step is skipped or quick when already done.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3.11}
command -v "$PYTHON" >/dev/null || PYTHON=python3

# System libraries: libusb for pyrealsense2 / open3d, GL + OpenMP for open3d, EGL for headless rendering.
DEB_PACKAGES=(libusb-1.0-0 libgl1 libgomp1 libegl1 libglib2.0-0)
missing=()
for p in "${DEB_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  echo "Installing system packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"
fi

[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
# On Python 3.11, the exact versions the tests and benchmarks were measured with (scripts/constraints.txt).
PINS=()
.venv/bin/python -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' && PINS=(-c scripts/constraints.txt)
# torch/torchvision first, pinned to the builds that match each other (see docs/quickstart.md).
.venv/bin/python -m pip install -q "${PINS[@]}" "torch==2.14.1" "torchvision==0.29.1"
.venv/bin/python -m pip install -q "${PINS[@]}" -e ".[dev,viewer,cluster,damiao]"  # the tests cover --view and --ray too
echo "axisloop installed: .venv/bin/deploy"
