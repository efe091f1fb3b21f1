#!/usr/bin/env bash
# artms-swarm's command line: validate accepts the shipped scenarios and
# reports every error of a bad file with file:line:column and field; run
# rejects bad arguments with a clear message and a non-zero exit.
set -uo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
fails=0
for f in "$SRC"/config/swarms/*.yaml; do
  "$BIN/artms-swarm" validate "$f" > "$WORK/out" 2>&1 || { echo "FAIL: $f does not validate"; cat "$WORK/out"; fails=$((fails+1)); }
done
cat > "$WORK/bad.yaml" <<'YAML'
name: bad
epoch: 2024-05-08T00:00:00Z
duration: 2h
spacecraft:
  - id: SV4
    kepler: {a_km: 6943, e: 1.3, i_deg: 99.4, raan_deg: 0, argp_deg: 0, M_deg: 0}
observers:
  - spacecraft: SV9
    camera: {cadence: -60s}
YAML
"$BIN/artms-swarm" validate "$WORK/bad.yaml" > "$WORK/out" 2>&1; rc=$?
[ $rc -eq 1 ] || { echo "FAIL: validate of a bad file exited $rc"; fails=$((fails+1)); }
for want in "bad.yaml:6:" "spacecraft[0].kepler.e" "bad.yaml:8:" "observers[0].spacecraft" "SV9" \
            "observers[0].camera.cadence" "3 error(s)"; do
  grep -qF "$want" "$WORK/out" || { echo "FAIL: validate output lacks '$want'"; cat "$WORK/out"; fails=$((fails+1)); }
done
"$BIN/artms-swarm" run "$WORK/bad.yaml" --out "$WORK/r" > "$WORK/out" 2>&1; rc=$?
[ $rc -eq 2 ] && grep -qF "spacecraft[0].kepler.e" "$WORK/out" || { echo "FAIL: run of a bad scenario: exit $rc"; cat "$WORK/out"; fails=$((fails+1)); }
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse.yaml" --rate fast --out "$WORK/r" > "$WORK/out" 2>&1; rc=$?
[ $rc -eq 2 ] && grep -q "rate must be" "$WORK/out" || { echo "FAIL: bad --rate: exit $rc"; cat "$WORK/out"; fails=$((fails+1)); }
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse.yaml" --duration 2x --out "$WORK/r" > "$WORK/out" 2>&1; rc=$?
[ $rc -eq 2 ] && grep -q "invalid duration '2x'" "$WORK/out" || { echo "FAIL: bad --duration: exit $rc"; cat "$WORK/out"; fails=$((fails+1)); }
echo "$fails failed"
[ $fails -eq 0 ]
