#!/usr/bin/env bash
# IMP inside the observer process, over real DDS: a 3-orbit PSE run with the
# flight-like profile (45 % drop-outs). The observer runs frame processing and
# SAMUS on the frames it receives and reports over the imp_report topic; the
# recorder writes imp/SV4/{attitude,measurements}.csv. Checked against the
# renderer's truth in frames.csv: attitude solved on >= 99 % of received
# frames, every tracked measurement on SV2's true pixel (within 3 px), and
# >= 80 % of the frames that show SV2 contribute a tracked measurement.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse_flight.yaml" --orbits 3 --out "$WORK/run" > "$WORK/swarm.out" 2>&1 \
  || { cat "$WORK/swarm.out"; exit 1; }
test -s "$WORK/run/uplink/star_catalog.csv" || { echo "FAIL: no onboard star catalog uplinked"; exit 1; }
/usr/bin/python3 - "$WORK/run" <<'PY'
import csv, math, sys
run = sys.argv[1]
att = list(csv.DictReader(open(f"{run}/imp/SV4/attitude.csv")))
meas = list(csv.DictReader(open(f"{run}/imp/SV4/measurements.csv")))
truth = {}
received = set()
for r in csv.DictReader(open(f"{run}/frames.csv")):
    if r["observer"] != "SV4" or r["dropped"] == "1":
        continue
    received.add(int(r["frame"]))
    if r["target"] == "SV2" and r["x_px"] not in ("", "nan") and r["reason"] in ("visible", "too faint"):
        truth[int(r["frame"])] = (float(r["x_px"]), float(r["y_px"]))
ok = sum(1 for a in att if a["status"] == "ok")
print(f"frames received {len(received)}, IMP reports {len(att)}, attitude ok {ok}")
assert len(att) >= len(received) - 1 and ok >= 0.99 * len(att), "attitude"
tracked = [m for m in meas if int(m["track_id"]) >= 0]
right = [m for m in tracked if int(m["frame"]) in truth and
         math.hypot(float(m["x_px"]) - truth[int(m["frame"])][0], float(m["y_px"]) - truth[int(m["frame"])][1]) < 3]
frames_hit = {int(m["frame"]) for m in right}
shown = {k for k in truth if k in received}
print(f"tracked measurements {len(tracked)}, on SV2 {len(right)}, tracks {sorted({m['track_id'] for m in tracked})}; "
      f"frames showing SV2 {len(shown)}, with a tracked measurement {len(frames_hit & shown)}")
assert tracked and len(right) >= 0.995 * len(tracked), "precision"
assert len(frames_hit & shown) >= 0.8 * len(shown), "recall"
print("swarm imp: ok")
PY
