#!/usr/bin/env bash
# Issue 5, acceptance 5: within a swarm run, frames reach the observer over
# DDS at its cadence with the configured drop-out rate (summary.json camera).
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse_flight.yaml" --duration 6h --seed 7 \
  --out "$WORK/run" > "$WORK/stdout" 2> "$WORK/stderr" || { cat "$WORK/stderr"; exit 1; }
/usr/bin/python3 - "$WORK/run" <<'PY'
import json, math, sys
s = json.load(open(f"{sys.argv[1]}/summary.json"))
c = s["camera"]["SV4"]
n, d, r = c["frames_scheduled"], c["frames_dropped"], c["frames_received"]
expected = int(s["sim_duration_s"] // c["cadence_s"]) + 1
assert n == expected, f"{n} frames scheduled, expected {expected} at the 60 s cadence"
p = 0.45
sigma = math.sqrt(p * (1 - p) / n)
assert abs(d / n - p) < 3 * sigma, f"drop-out rate {d/n:.3f} not within 3 sigma of {p}"
# Frames of step k are consumed at step k+1: all but the last published frame.
published = n - d
assert r in (published, published - 1), f"observer received {r} frames, {published} were published"
print(f"frames: {n} scheduled at 60 s, {d} dropped ({100*d/n:.1f} %, configured 45 %), "
      f"{r} received by observer-SV4 over DDS")
PY
