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
/usr/bin/python3 - "$WORK" <<'PY'
import json, sys, filecmp, os
work = sys.argv[1]
for run in "AB":
    s = json.load(open(f"{work}/{run}/summary.json"))
    bad = [p for p in s["processes"] if p["exit_code"] != 0]
    assert not bad, f"run {run}: processes with non-zero exit: {bad}"
    assert len(s["processes"]) >= 5, s["processes"]
def files(root):
    out = []
    for d, _, fs in os.walk(root):
        for f in fs:
            rel = os.path.relpath(os.path.join(d, f), root)
            if rel == "timing.json" or rel.startswith("logs" + os.sep):
                continue
            out.append(rel)
    return sorted(out)
fa, fb = files(f"{work}/A"), files(f"{work}/B")
assert fa == fb, f"different file sets: {set(fa) ^ set(fb)}"
diff = [f for f in fa if not filecmp.cmp(f"{work}/A/{f}", f"{work}/B/{f}", shallow=False)]
assert not diff, f"files differ between A and B: {diff}"
t = json.load(open(f"{work}/A/timing.json"))
print(f"determinism: {len(fa)} files identical; real-time factor {t['real_time_factor']:.0f}x "
      f"({t['sim_time_s']:.0f} s simulated in {t['wall_time_s']:.1f} s)")
PY
