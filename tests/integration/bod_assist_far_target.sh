#!/usr/bin/env bash
# Issue 16, acceptance 3, for the far target: in integration.swarm_bod's run
# of starling_bod_assist.yaml (19 h, seed 7), T150 (~150 km, 3.5-day
# a-priori) converges (a*dlambda within 1 % of range to the end) within 6
# orbits. Not met since stop 52: with the stars' aberration in the frames
# (a new noise draw; its bearings unbiased, error / 1-sigma RMS 1.04) it
# converges at 7.44 orbits (stop 51: 4.72), its error at 1.5-2 sigma near
# 1 % for orbits 3-9 (docs/bod.md, "Stop 52"); at 6.39 orbits since stop
# 53's constant false-alarm threshold (18 of 20 seeds within 6; docs/bod.md,
# "Stop 53"). This script prints the
# verdict; CMakeLists.txt expects "NOT MET" until the point is met, so the
# test fails when it is met (update the docs and the expectation) or when
# it cannot be checked.
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
