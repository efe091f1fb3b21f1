#!/usr/bin/env bash
# Issue 8 (crosslink), test (a): starling_it_pair.yaml (SV4 and SV2 observe
# and broadcast every 60 s) for 2 h with every link down from 00:30 to 01:15.
# Every process exits 0; per link sent = delivered + dropped; dropped.outage
# > 0 and equal to the broadcasts relayed inside the window (45 per link);
# deliveries before and after; links.csv up -> down (outage) -> up; isl.csv
# and summary.json agree; receivers counted what was delivered and kept
# navigating (one telemetry row per step) through the outage.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_it_pair.yaml" --duration 2h --out "$WORK/run" \
    > "$WORK/swarm.out" 2>&1 || { cat "$WORK/swarm.out"; tail -n 20 "$WORK"/run/logs/*.log; exit 1; }
/usr/bin/python3 "$SRC/tests/integration/isl_check.py" "$WORK/run" --outage 1800 4500
/usr/bin/python3 - "$WORK/run/summary.json" <<'PY'
import json, sys
isl = json.load(open(sys.argv[1]))["isl"]
for key, L in isl["per_link"].items():
    assert L["dropped"]["outage"] == 45, (key, L)
    assert L["dropped"]["loss"] == 0 and L["dropped"]["range"] == 0, (key, L)
print("swarm isl outage: ok")
PY
