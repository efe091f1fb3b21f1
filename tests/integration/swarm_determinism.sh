#!/usr/bin/env bash
# Issue 4, acceptance 1 (and 5): the same scenario and seed twice; exit 0,
# every process exit_code 0 in summary.json, and the two run folders
# byte-identical apart from timing.json (and logs/, the processes' stderr).
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
DURATION=${ARTMS_DET_DURATION:-2h}
rm -rf "$WORK"; mkdir -p "$WORK"
for run in A B; do
  "$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse.yaml" --duration "$DURATION" --seed 7 \
      --out "$WORK/$run" > "$WORK/$run.stdout" 2> "$WORK/$run.stderr" \
    || { echo "run $run failed:"; cat "$WORK/$run.stderr" "$WORK/$run.stdout"; tail -n 20 "$WORK/$run"/logs/*.log; exit 1; }
done
/usr/bin/python3 "$SRC/tests/integration/compare_runs.py" "$WORK/A" "$WORK/B"
/usr/bin/python3 - "$WORK" <<'PY'
import json, sys
work = sys.argv[1]
s = json.load(open(f"{work}/A/summary.json"))
assert len(s["processes"]) >= 5, s["processes"]
t = json.load(open(f"{work}/A/timing.json"))
print(f"determinism: real-time factor {t['real_time_factor']:.0f}x "
      f"({t['sim_time_s']:.0f} s simulated in {t['wall_time_s']:.1f} s)")
PY
