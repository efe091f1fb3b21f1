#!/usr/bin/env bash
# Long soak for users (issue 8, acceptance 4): the four-observer soak scenario
# for DURATION (default 7 days) with the checks of the CI soak test (every
# process exits 0, resident memory growth < 10 % from hour 6 to the end,
# filters healthy at the end, exact crosslink accounting), printing its
# figures. Usage: scripts/soak.sh [DURATION] [WORK_DIR]   (e.g. 7d, 48h)
# Build first (scripts/build.sh). About 25 minutes for 7 days on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
DURATION=${1:-7d}
WORK=${2:-runs/soak-$DURATION}
export CYCLONEDDS_URI=${CYCLONEDDS_URI:-file://$PWD/config/cyclonedds-loopback.xml}
ARTMS_BIN=$PWD/build/bin ARTMS_SOURCE_DIR=$PWD ARTMS_SOAK_DURATION=$DURATION \
  bash tests/integration/soak_four_observers.sh "$WORK"
