#!/usr/bin/env bash
# artms-imp over frames rendered by artms-render (PSE, flight-like, 45 %
# drop-outs): attitude solved on every frame with >= 4 catalog stars, none
# wrong by more than 1 arcmin, target detections within 15 arcsec; a corrupt
# frame is reported and skipped, not fatal.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
"$BIN/artms-render" "$SRC/config/swarms/starling_pse_flight.yaml" --observer SV4 --count 30 --every 60s \
  --out "$WORK/frames" 2> "$WORK/render.err"
# A corrupt frame in the middle of the sequence.
printf 'not a png' > "$WORK/frames/frame_000999.png"
# --observer-orbit: the frames' stars carry the observer's stellar aberration
# (up to ~26"), which artms-imp takes out of the attitude with its velocity.
"$BIN/artms-imp" "$SRC/config/cameras/nst.yaml" "$WORK/frames" --observer-orbit "$WORK/frames/observer_orbit.csv" \
  --out "$WORK/imp" 2> "$WORK/imp.err"
grep -q "skipping .*frame_000999.png" "$WORK/imp.err" || { echo "FAIL: corrupt frame not reported"; cat "$WORK/imp.err"; exit 1; }
grep -q "^999,.*,corrupt," "$WORK/imp/attitude.csv" || { echo "FAIL: corrupt frame not in attitude.csv"; exit 1; }
/usr/bin/python3 "$SRC/tools/artms_imp/evaluate_imp.py" "$WORK/frames" "$WORK/imp" --json "$WORK/eval.json"
/usr/bin/python3 - "$WORK/eval.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
assert r["frames_with_4_stars"] >= 10, r
assert r["solved_fraction"] >= 0.99, r
assert r["accepted_wrong_gt_1arcmin"] == 0, r
assert r["cross_boresight_1sigma_arcsec"] < 10, r
assert r["target_detections_matched"] >= 5 and r["target_bearing_1sigma_arcsec"] < 15, r
print("imp offline: ok")
PY
