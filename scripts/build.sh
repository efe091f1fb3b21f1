#!/usr/bin/env bash
# Configures and builds the project into build/ (Release with debug info).
# Usage: scripts/build.sh [extra cmake -D options]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${ARTMS_BUILD_DIR:-build}
JOBS=${ARTMS_JOBS:-2}
WERROR=OFF
if [ "${CI:-}" = "true" ]; then WERROR=ON; fi
cmake -S . -B "$BUILD_DIR" -G Ninja -DARTMS_WERROR="$WERROR" "$@"
cmake --build "$BUILD_DIR" -j "$JOBS"
