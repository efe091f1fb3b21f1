#!/usr/bin/env bash
# BOD (issue 16), in-process runs (the DDS path of the same objects is pinned
# by swarm_in_process):
#  1. navigation mode 2, starling_pse_bod.yaml 4 h seed 7: SV2 has no
#     a-priori of SV4; BOD initialises it from its IMP track within 2 orbits,
#     the first estimate's dlambda error is <= 5 % of range and inside 3 sigma,
#     bod/SV2.csv records the attempt that did it and its residual curve;
#     SV2's camera clock is off by a drawn residual that SOD estimates, so
#     SOD's first 1-sigma holds BOD's own and the clock's doubt
#     (Navigator::add_clock_doubt): more than 1.5 x BOD's recorded sigma;
#  2. starling_pse_burn_large.yaml 11 h: SV2 burns 0.5 m/s along-track at
#     08:00; SV4's navigator names health check 1 and re-initialises SV2 from
#     BOD before 11:00 (two BOD periods);
#  3. starling_pse_bod_two.yaml 4 h with the flight-like photometry: SV3 at
#     ~155 km is too faint in every frame; SV4's navigator says at each BOD
#     attempt that SV3 still waits for BOD, and summary.json gives SV3 an
#     entry "never estimated" with the frames' reasons (nothing silent);
#  4. starling_bod_assist.yaml (issue 16, acceptance 3), 19 h seed 7: SV4 in
#     mode 1 with the 3.5-day a-priori of T20 (~20 km, bound only after BOD)
#     and T150: both converge (a*dlambda within 1 % of range to the end);
#     T20 within 6 orbits. T150's "within 6 orbits" is its own test,
#     integration.bod_assist_far_target (tests/integration/CMakeLists.txt:
#     not met from stop 52 to stop 60, met since stop 61's stacked aided
#     search: 0.42 orbits), which reads this run's summary.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse_bod.yaml" --in-process --duration 4h --seed 7 \
  --no-report --out "$WORK/mode2" > "$WORK/mode2.out" 2>&1 || { tail -30 "$WORK/mode2.out"; exit 1; }
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse_burn_large.yaml" --in-process --duration 11h --seed 7 \
  --no-report --out "$WORK/burn" > "$WORK/burn.out" 2>&1 || { tail -30 "$WORK/burn.out"; exit 1; }
sed 's/profile: nominal/profile: flight-like/' "$SRC/config/swarms/starling_pse_bod_two.yaml" > "$WORK/two_faint.yaml"
grep -q "profile: flight-like" "$WORK/two_faint.yaml"
"$BIN/artms-swarm" run "$WORK/two_faint.yaml" --in-process --duration 4h --seed 7 \
  --no-report --out "$WORK/two_faint" > "$WORK/two_faint.out" 2>&1 || { tail -30 "$WORK/two_faint.out"; exit 1; }
"$BIN/artms-swarm" run "$SRC/config/swarms/starling_bod_assist.yaml" --in-process --seed 7 \
  --no-report --out "$WORK/assist" > "$WORK/assist.out" 2>&1 || { tail -30 "$WORK/assist.out"; exit 1; }
/usr/bin/python3 - "$WORK" <<'PY'
import csv, json, sys
work = sys.argv[1]
t = json.load(open(f"{work}/mode2/summary.json"))["observers"]["SV2"]["targets"]["SV4"]
print(f"mode 2: SV4 first estimate at {t['first_estimate_orbits']:.2f} orbits, dlambda error "
      f"{t['initial_dlambda_error_pct']:+.2f} % (1-sigma {t['initial_dlambda_sigma_pct']:.2f} %)")
assert t["first_estimate_orbits"] <= 2.0, t
assert abs(t["initial_dlambda_error_pct"]) <= 5.0, t
assert t["initial_within_3sigma"], t
rows = list(csv.DictReader(open(f"{work}/mode2/bod/SV2.csv")))
init = [r for r in rows if r["action"].startswith("SOD initialised from BOD")]
assert init and init[0]["verdict"] == "0" and init[0]["target"] == "SV4", rows
curve = [r for r in csv.DictReader(open(f"{work}/mode2/bod/SV2_curves.csv")) if r["attempt"] == init[0]["attempt"]]
assert len(curve) >= 50, len(curve)
bod_sigma_pct = 100 * float(init[0]["sigma_range_m"]) / float(init[0]["range_m"])
print(f"mode 2: BOD's own range 1-sigma {bod_sigma_pct:.2f} %, SOD's first {t['initial_dlambda_sigma_pct']:.2f} % "
      f"with the camera clock's doubt")
assert t["initial_dlambda_sigma_pct"] > 1.5 * bod_sigma_pct, (t, bod_sigma_pct)
log = open(f"{work}/burn/events.log").read().splitlines()
hits = [l for l in log if "SV2 unhealthy (health check 1" in l and "re-initialised from BOD" in l]
assert hits, "no health check 1 on SV2 after its burn"
when = hits[0][11:16]
print(f"burn: {hits[0][:160]}")
assert "08:00" < when <= "11:00", when
s3 = json.load(open(f"{work}/two_faint/summary.json"))["observers"]["SV4"]["targets"]
assert s3["SV2"].get("estimated") is True, s3["SV2"]
assert s3["SV3"]["estimated"] is False and s3["SV3"]["frames_visible"] == 0, s3["SV3"]
assert "too faint" in s3["SV3"]["why"], s3["SV3"]
waits = [l for l in open(f"{work}/two_faint/events.log") if "target SV3 still waits for BOD" in l]
assert len(waits) >= 2, "no 'SV3 still waits for BOD' event at the BOD attempts"
print(f"faint SV3: {s3['SV3']['why']}; {len(waits)} waiting events")
ta = json.load(open(f"{work}/assist/summary.json"))["observers"]["SV4"]["targets"]
for k in ("T20", "T150"):
    t = ta[k]
    print(f"a-priori too poor: {k} converged at {t['convergence_orbits']} orbits, final dlambda error "
          f"{t['final_dlambda_error_pct']:.3f} % (1-sigma {t['final_dlambda_sigma_pct']:.3f} %)")
    assert t["convergence_orbits"] is not None, (k, t)
    if k == "T20":
        assert t["convergence_orbits"] <= 6.0, (k, t)
    assert abs(t["final_dlambda_error_pct"]) <= 1.0, (k, t)
print("swarm_bod: ok")
PY
