#!/usr/bin/env bash
# Issue 8 (crosslink), test (b): starling_it_pair.yaml without outages and
# with crosslink.loss_probability 0.3, 2 h: per link sent = delivered +
# dropped, and dropped.loss within 3 sigma of 0.3 * (relays on up links).
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
sed -e '/^  outages:/,/every link down/d' -e 's/^  use_remote_gnss: false.*/&\n  loss_probability: 0.3/' \
    "$SRC/config/swarms/starling_it_pair.yaml" > "$WORK/lossy.yaml"
grep -q "loss_probability: 0.3" "$WORK/lossy.yaml" && ! grep -q "outages:" "$WORK/lossy.yaml"
"$BIN/artms-swarm" run "$WORK/lossy.yaml" --duration 2h --out "$WORK/run" \
    > "$WORK/swarm.out" 2>&1 || { cat "$WORK/swarm.out"; tail -n 20 "$WORK"/run/logs/*.log; exit 1; }
/usr/bin/python3 "$SRC/tests/integration/isl_check.py" "$WORK/run" --loss 0.3
/usr/bin/python3 - "$WORK/run/summary.json" <<'PY'
import json, sys
isl = json.load(open(sys.argv[1]))["isl"]
for key, L in isl["per_link"].items():
    assert L["dropped"]["outage"] == 0 and L["dropped"]["loss"] > 0, (key, L)
print("swarm isl loss: ok")
PY
