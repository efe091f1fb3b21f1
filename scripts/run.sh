#!/usr/bin/env bash
# The main job: installs, builds and runs the default swarm scenario end to end.
#
# Until the swarm runtime exists (issue 4) this builds everything, runs the
# astrodynamics self-check on the default scenario's formation (Table 2, PSE)
# and says what is still to come. The command stays the same afterwards.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
BIN=${ARTMS_BUILD_DIR:-build}/bin
if [ -x "$BIN/artms-swarm" ]; then
  exec "$BIN/artms-swarm" run config/swarms/starling_pse.yaml --orbits 3 "$@"
fi
echo
echo "== ARTMS emulator: foundation build =="
for tool in "$BIN"/artms-*; do
  [ -x "$tool" ] || continue
  echo "--- $(basename "$tool") --help"
  "$tool" --help
done
"$BIN/artms_astro_tests" --gtest_brief=1 --gtest_filter='Roe.LinearMapErrorForTable2Formations'
echo
echo "The multi-process swarm (artms-swarm run config/swarms/starling_pse.yaml) arrives with"
echo "the swarm runtime (issue 4); this command will then run it unchanged."
