#!/usr/bin/env bash
# Installs every build, test and oracle dependency from Debian 12 packages.
# Idempotent: packages already present are left alone. Needs root (or sudo).
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  # middleware and mathematics
  cyclonedds-dev cyclonedds-tools libeigen3-dev libsundials-dev libyaml-cpp-dev
  # imaging: only the OpenCV components the project uses
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev
  # FITS frames for artms-imp (CFITSIO)
  libcfitsio-dev
  # CLI parsing, logging, formatting, JSON
  libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # independent oracles for tests (Debian's python3 at /usr/bin/python3)
  python3 python3-numpy python3-scipy python3-poliastro python3-sklearn python3-skyfield
  # image files for the real-frame tests (PIL: mirrored PNGs; astropy: FITS)
  python3-pil python3-astropy
  # plots for artms-report helpers and docs
  python3-matplotlib
  # campaigns on a cluster engine (tools/artms_swarm/campaign.py --dask-*)
  python3-distributed
  # network namespaces for multi-host tests
  iproute2 procps
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "install-deps: done"
