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
# Until the swarm exists: the truth of the default scenario's observer, SV4 in
# the PSE formation (Table 2), over three orbits with the full force model.
OUT=${ARTMS_RUN_DIR:-runs/foundation}
mkdir -p "$OUT"
"$BIN/artms-propagate" --epoch 2024-05-08T00:00:00Z --oe 6943000,0.0016,99.4,-38,86.4,-239.4 \
  --duration 5h --step 60s --force grav10,drag,sun,moon --name SV4 \
  --out "$OUT/sv4.csv" --oem "$OUT/sv4.oem"
echo "SV4 truth over three orbits: $OUT/sv4.csv and $OUT/sv4.oem"
echo
echo "The multi-process swarm (artms-swarm run config/swarms/starling_pse.yaml) arrives with"
echo "the swarm runtime (issue 4); this command will then run it unchanged."
