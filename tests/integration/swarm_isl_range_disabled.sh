#!/usr/bin/env bash
# Issue 8 (crosslink accounting), the drop reasons other than outage and
# loss: starling_it_pair.yaml without outages for 1 h,
#  (a) crosslink.max_range_km 100: SV4 and SV2 are ~125 km apart, so every
#      broadcast on both links is dropped for "range" and links.csv says the
#      links are down for range;
#  (b) crosslink.enabled false: every broadcast is dropped for "disabled".
# In both, per link sent = delivered + dropped exactly (isl_check.py), the
# observers keep navigating (exit 0) and receive nothing.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
sed -e '/^  outages:/,/every link down/d' -e 's/^  use_remote_gnss: false.*/&\n  max_range_km: 100/' \
    "$SRC/config/swarms/starling_it_pair.yaml" > "$WORK/range.yaml"
sed -e '/^  outages:/,/every link down/d' -e 's/^  enabled: true/  enabled: false/' \
    "$SRC/config/swarms/starling_it_pair.yaml" > "$WORK/disabled.yaml"
grep -q "max_range_km: 100" "$WORK/range.yaml" && grep -q "^  enabled: false" "$WORK/disabled.yaml"
for case in range disabled; do
  "$BIN/artms-swarm" run "$WORK/$case.yaml" --duration 1h --out "$WORK/$case" \
      > "$WORK/$case.out" 2>&1 || { cat "$WORK/$case.out"; tail -n 20 "$WORK/$case"/logs/*.log; exit 1; }
  /usr/bin/python3 "$SRC/tests/integration/isl_check.py" "$WORK/$case"
  /usr/bin/python3 - "$WORK/$case" "$case" <<'PY'
import csv, json, sys
run, reason = sys.argv[1], sys.argv[2]
isl = json.load(open(f"{run}/summary.json"))["isl"]
for key, L in isl["per_link"].items():
    assert L["delivered"] == 0 and L["dropped"][reason] == L["sent"] > 0, (key, L)
    print(f"  {key}: {L['sent']} sent, all dropped for {reason}")
for obs in ("SV4", "SV2"):
    last = list(csv.DictReader(open(f"{run}/nav/{obs}.csv")))[-1]
    assert int(last["isl_received"]) == 0 and int(last["isl_sent"]) > 0, (obs, last)
if reason == "range":
    rows = list(csv.DictReader(open(f"{run}/links.csv")))
    assert rows and all(r["up"] in ("0", "false") and "range" in r["reason"] for r in rows), rows[:3]
print(f"swarm isl {reason}: ok")
PY
done
