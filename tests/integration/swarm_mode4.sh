#!/usr/bin/env bash
# Navigation mode 4 (issue 18): starling_it_mode4.yaml, three observers, no GNSS.
#  1. Real processes on Cyclone DDS, 1 h: every observer's telemetry and ISL
#     broadcasts carry source 4 (bearings only) from the first step, no GNSS
#     fix of an observer is produced, SOD starts from the uplinked coarse orbit.
#  2. In-process, 12 h seed 7: SV4's absolute position error falls from
#     ~6.9 km to below half of it, never beyond 3 sigma in any RTN axis, and
#     every pair's dlambda error ends within 1 % of range.
#  3. artms-sod-replay on that run folder for SV4 (mode 4: coarse orbit, every
#     observer's recorded bearings, no GNSS), with the recorded bearings and
#     with synthetic white ones: own and remote bearings fused, the position
#     error falls below half the coarse orbit's; --bearings pixel refused;
#     --leave-out removes the bearings it names, --start-roe truth is said;
#     target-to-target lines as consider updates by default (the scenario's
#     tuning.sod.target_lines), as full updates with --target-lines.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
export CYCLONEDDS_URI=${CYCLONEDDS_URI:-file://$SRC/config/cyclonedds-loopback.xml}
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_it_mode4.yaml" --duration 1h --seed 7 \
  --no-report --out "$WORK/dds" > "$WORK/dds.out" 2>&1 || { tail -30 "$WORK/dds.out"; exit 1; }
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_it_mode4.yaml" --in-process --duration 12h --seed 7 \
  --no-report --out "$WORK/inproc" > "$WORK/inproc.out" 2>&1 || { tail -30 "$WORK/inproc.out"; exit 1; }
/usr/bin/python3 - "$WORK" <<'PY'
import csv, json, sys
work = sys.argv[1]
for obs in ("SV2", "SV3", "SV4"):
    rows = list(csv.DictReader(open(f"{work}/dds/nav/{obs}.csv")))
    assert rows and all(r["source"] == "4" and r["mode"] == "4" for r in rows), (obs, rows[:2])
gnss = [r for r in csv.DictReader(open(f"{work}/dds/gnss.csv")) if r["valid"] == "1"]
assert not gnss, gnss[:2]
isl = list(csv.DictReader(open(f"{work}/dds/isl.csv")))
assert isl and all(r["source"] == "4" for r in isl), isl[:2]
log = open(f"{work}/dds/events.log").read()
assert log.count("SOD initialised at the uplinked coarse orbit") == 3, log[:2000]
s = json.load(open(f"{work}/inproc/summary.json"))["observers"]
a = s["SV4"]["absolute"]
print(f"SV4 absolute: {a['initial_position_error_m']:.0f} m -> {a['final_pos_error_m']:.0f} m "
      f"(1-sigma {a['final_pos_sigma_m']:.0f} m), max |error|/sigma {a['max_rtn_error_over_sigma']:.2f}")
assert 5000 < a["initial_position_error_m"] < 9000, a
assert a["final_pos_error_m"] < 0.5 * a["initial_position_error_m"], a
assert a["max_rtn_error_over_sigma"] < 3.0, a
assert a["angles_only_fraction"] == 1.0, a
for obs, o in s.items():
    for tgt, t in o["targets"].items():
        print(f"{obs}->{tgt}: dlambda error {t['final_dlambda_error_pct']:.3f} % of range")
        assert t["final_dlambda_error_pct"] <= 1.0, (obs, tgt, t)
PY
for m in measured synthetic; do
  "$BIN/artms-sod-replay" "$WORK/inproc" --observer SV4 --bearings $m --after-orbits 2 > "$WORK/replay_$m.out" \
    || { cat "$WORK/replay_$m.out"; exit 1; }
done
if "$BIN/artms-sod-replay" "$WORK/inproc" --observer SV4 --bearings pixel 2> "$WORK/replay_pixel.err"; then
  echo "FAIL: --bearings pixel accepted in mode 4"; exit 1
fi
grep -q "modes 1 and 3 only" "$WORK/replay_pixel.err"
if "$BIN/artms-sod-replay" "$WORK/inproc" --observer SV4 --innovations "$WORK/inn.csv" 2> "$WORK/replay_inn.err"; then
  echo "FAIL: --innovations accepted in mode 4"; exit 1
fi
grep -q -- "--innovations: modes 1 and 3 only" "$WORK/replay_inn.err" || { cat "$WORK/replay_inn.err"; exit 1; }
"$BIN/artms-sod-replay" "$WORK/inproc" --observer SV4 --bearings synthetic --leave-out 'SV3>SV2' > "$WORK/replay_leave.out"
"$BIN/artms-sod-replay" "$WORK/inproc" --observer SV4 --bearings synthetic --noise-scale 0 --start-roe truth \
  > "$WORK/replay_truth.out"
grep -q "targets started at their true ROE" "$WORK/replay_truth.out" || { cat "$WORK/replay_truth.out"; exit 1; }
"$BIN/artms-sod-replay" "$WORK/inproc" --observer SV4 --target-lines update_observer > "$WORK/replay_update.out"
grep -q "target-to-target lines: update_observer" "$WORK/replay_update.out" || { cat "$WORK/replay_update.out"; exit 1; }
grep -q "target-to-target lines: consider_observer" "$WORK/replay_measured.out" || { cat "$WORK/replay_measured.out"; exit 1; }
/usr/bin/python3 - "$WORK" <<'PY'
import json, re, sys
work = sys.argv[1]
a = json.load(open(f"{work}/inproc/summary.json"))["observers"]["SV4"]["absolute"]
for m in ("measured", "synthetic"):
    out = open(f"{work}/replay_{m}.out").read()
    print(out.strip())
    own, own_n, rem, rem_n = map(int, re.search(r"own bearings fused (\d+) of (\d+), remote (\d+) of (\d+)", out).groups())
    assert own > 100 and rem > own and own >= 0.9 * own_n and rem >= 0.9 * rem_n, out
    final = float(re.search(r"final error (\d+) m", out).group(1))
    assert final < 0.5 * a["initial_position_error_m"], (m, final, a)
full = re.search(r"remote \d+ of (\d+)", open(f"{work}/replay_synthetic.out").read()).group(1)
out = open(f"{work}/replay_leave.out").read()
rem, left = map(int, re.search(r"remote \d+ of (\d+), (\d+) left out", out).groups())
assert left > 0 and rem + left == int(full), (full, out)
print(f"--leave-out 'SV3>SV2': {left} bearings left out, {rem} remote fused")
print("swarm_mode4: ok")
PY
