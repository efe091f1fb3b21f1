#!/usr/bin/env bash
# Issue 4, acceptance 2: kill one observer mid-run. The launcher exits
# non-zero naming it, no process is left behind, and the run folder holds
# what was recorded up to then.
set -uo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
OUT="$WORK/run"
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse.yaml" --duration 2d --seed 3 --out "$OUT" \
  > "$WORK/stdout" 2> "$WORK/stderr" &
LAUNCHER=$!
# Wait until the observer has navigated a while (nav lines recorded).
for _ in $(seq 1 600); do
  n=$(wc -l < "$OUT/nav/SV4.csv" 2>/dev/null || echo 0)
  [ "$n" -gt 30 ] && break
  sleep 0.1
done
OBS=$(pgrep -f "artms-observer .*--out $OUT" | head -1)
[ -n "$OBS" ] || { echo "FAIL: observer process not found"; cat "$WORK/stderr"; kill $LAUNCHER; exit 1; }
kill -9 "$OBS"
wait $LAUNCHER; rc=$?
fails=0
[ $rc -ne 0 ] || { echo "FAIL: launcher exited 0 after an observer was killed"; fails=1; }
grep -q "observer-SV4 was killed by signal 9" "$WORK/stderr" || { echo "FAIL: launcher did not name observer-SV4"; cat "$WORK/stderr"; fails=1; }
sleep 0.5
left=$(pgrep -f -- "--out $OUT" || true)
[ -z "$left" ] || { echo "FAIL: processes left behind: $left"; ps -fp $left; pkill -9 -f -- "--out $OUT"; fails=1; }
n=$(wc -l < "$OUT/nav/SV4.csv")
[ "$n" -gt 30 ] || { echo "FAIL: nav/SV4.csv has only $n lines"; fails=1; }
[ -s "$OUT/truth.oem" ] || { echo "FAIL: no truth.oem kept"; fails=1; }
grep -q '"exit_code": 137' "$OUT/summary.json" || { echo "FAIL: summary.json lacks the killed process's code"; fails=1; }
echo "kill test: launcher exit $rc, nav lines kept $n, truth.oem $(wc -l < "$OUT/truth.oem") lines"
exit $fails
