#!/usr/bin/env bash
# The main job: installs, builds and runs the default swarm scenario end to
# end (config/swarms/starling_pse.yaml, three orbits, one process per
# spacecraft over Cyclone DDS on the loopback interface). Extra arguments go
# to `artms-swarm run` (e.g. --orbits 12, --seed 3, --out DIR).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
BIN=${ARTMS_BUILD_DIR:-build}/bin
if [ ! -x "$BIN/artms-swarm" ]; then
  echo "run.sh: $BIN/artms-swarm was not built (see the build output above)" >&2
  exit 1
fi
exec "$BIN/artms-swarm" run config/swarms/starling_pse.yaml --orbits 3 "$@"
