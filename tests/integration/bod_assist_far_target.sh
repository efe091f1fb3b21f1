#!/usr/bin/env bash
# Issue 16, acceptance 3, for the far target: in integration.swarm_bod's run
# of starling_bod_assist.yaml (19 h, seed 7), T150 (~150 km, 3.5-day
# a-priori) converges (a*dlambda within 1 % of range to the end) within 6
# orbits. Not met from stop 52 to stop 60 (7.44 orbits at stop 52, 6.37-6.42
# from stop 53: T150's bearings are SOD-aided detections in 12 % of its
# frames, docs/bod.md "Stop 52"-"Stop 55"); met since stop 61, when the
# aided search on the last four frames summed along T150's predicted pixel
# (tuning.imp.aided_stack_frames, default 4) became the default: 0.42
# orbits (docs/bod.md, "Stop 61"). This script prints the verdict;
# CMakeLists.txt expects "MET", so the test fails when the point is lost
# or when it cannot be checked.
set -euo pipefail
WORK=${1:?}
SUMMARY="$(dirname "$WORK")/swarm_bod/assist/summary.json"
if [ ! -f "$SUMMARY" ]; then
  echo "cannot check: no $SUMMARY (integration.swarm_bod did not run)"
  exit 1
fi
/usr/bin/python3 - "$SUMMARY" <<'PY'
import json, sys
t = json.load(open(sys.argv[1]))["observers"]["SV4"]["targets"]["T150"]
c = t["convergence_orbits"]
met = c is not None and c <= 6.0
print(f"T150 converged at {c} orbits (asked: <= 6), final dlambda error {t['final_dlambda_error_pct']:.3f} % "
      f"(1-sigma {t['final_dlambda_sigma_pct']:.3f} %)")
print("issue 16 acceptance 3 for T150: " + ("MET" if met else "NOT MET"))
PY
