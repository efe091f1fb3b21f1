#!/usr/bin/env bash
# Issue 15, acceptance 3: starling_it_multi.yaml (three observers, ISL) for
# 3 h with seed 7, twice in the DDS multi-process run while the machine is
# loaded by an in-process run of another scenario: byte-identical run
# folders (timing.json and logs/ aside). The ISL relays of a step are
# decided at the next step whatever the arrival order (sim::Crosslink).
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
DURATION=${ARTMS_DET_DURATION:-3h}
rm -rf "$WORK"; mkdir -p "$WORK"
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse.yaml" --orbits 6 --in-process --out "$WORK/load" \
    > "$WORK/load.out" 2>&1 &
load=$!
for run in A B; do
  "$BIN/artms-swarm" run "$SRC/config/swarms/starling_it_multi.yaml" --duration "$DURATION" --seed 7 \
      --out "$WORK/$run" > "$WORK/$run.out" 2>&1 \
    || { echo "run $run failed:"; tail -n 30 "$WORK/$run.out"; tail -n 20 "$WORK/$run"/logs/*.log; kill $load 2>/dev/null; exit 1; }
done
kill $load 2>/dev/null || true
wait $load 2>/dev/null || true
/usr/bin/python3 "$SRC/tests/integration/compare_runs.py" "$WORK/A" "$WORK/B"
# The relays of the first broadcasts land one step after they were sent.
/usr/bin/python3 - "$WORK/A/isl.csv" <<'PY'
import csv, sys
rows = [r for r in csv.DictReader(open(sys.argv[1])) if r["reason"] != "end_of_run"]
assert rows, "no relays"
lag = {int(r["t_tt_ns"]) - int(r["t_sent_tt_ns"]) for r in rows}
assert lag == {60_000_000_000}, lag
print(f"{len(rows)} relays, each decided 60 s after it was sent")
PY
echo "swarm multi-observer determinism: ok"
