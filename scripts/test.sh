#!/usr/bin/env bash
# The whole test suite, from a fresh Debian 12 machine: installs what it needs
# (apt-get, root or sudo), builds, and runs every ctest label
# (unit, oracle, integration, soak, bench).
# Usage: scripts/test.sh [extra ctest arguments, e.g. -L unit]
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
cd "${ARTMS_BUILD_DIR:-build}"
# Cyclone DDS stays on loopback with multicast off (DESIGN.md section 9).
export CYCLONEDDS_URI=${CYCLONEDDS_URI:-file://$PWD/../config/cyclonedds-loopback.xml}
ctest --output-on-failure -j "${ARTMS_JOBS:-2}" --timeout 1500 "$@"
