#!/usr/bin/env bash
# artms-report on fabricated run folders: a complete one (2 targets, 300 rows
# each, local and remote measurements, a re-initialisation and a no-solution
# gap, two BOD attempts with their residual curves; no truth.oem: the BOD
# range errors come from eval/targets.csv's range_m), one without
# eval/observers.csv and with nulls in summary.json, an empty one (no crash,
# exit 1) and a missing one (exit 2).
set -euo pipefail
BIN=${ARTMS_BIN:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
/usr/bin/python3 - "$WORK" <<'PY'
import csv, json, math, os, random, sys
work = sys.argv[1]
random.seed(7)
ROE = ["da", "dlambda", "dex", "dey", "dix", "diy"]

def fabricate(run, with_observers, nulls):
    os.makedirs(os.path.join(run, "eval"), exist_ok=True)
    t0_ns, dt = 769_000_000 * 10**9, 120.0
    ranges = {"SV2": 50e3, "SV3": 130e3}
    with open(os.path.join(run, "eval", "targets.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_utc", "t_tt_ns", "observer", "target", "range_m"]
                   + [f"err_a_{k}_m" for k in ROE] + [f"sigma_a_{k}_m" for k in ROE]
                   + ["local_measurements", "remote_measurements", "health"])
        for tgt, rng in ranges.items():
            loc = rem = 0
            e = [0.0] * 6
            for i in range(300):
                t = i * dt
                decay = math.exp(-t / 8000.0)
                sig = [rng * (0.0001 + 0.01 * decay)] * 6
                sig[1] = rng * (0.012 + 0.2 * decay)
                e = [0.9 * ek + 0.3 * random.gauss(0, s) for ek, s in zip(e, sig)]
                if random.random() < (0.8 if tgt == "SV2" else 0.1):
                    loc += 1
                if tgt == "SV3" and random.random() < 0.3:
                    rem += 1
                health = 1 if 150 <= i < 155 else (2 if 200 <= i < 203 else 0)
                utc = f"2024-05-16T{int(t // 3600):02d}:{int(t % 3600 // 60):02d}:{int(t % 60):02d}Z"
                vals = [""] * 12 if health == 2 else [f"{v:.4f}" for v in e + sig]
                w.writerow([utc, t0_ns + int(t * 1e9), "SV4", tgt, f"{rng:.1f}"] + vals + [loc, rem, health])
    if with_observers:
        with open(os.path.join(run, "eval", "observers.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["t_utc", "t_tt_ns", "observer", "mode", "source", "pos_err_m", "vel_err_mps",
                        "sigma_pos_m", "sigma_vel_mps"])
            for i in range(300):
                t = i * dt
                src = "gnss" if i < 100 else "angles"
                w.writerow(["", t0_ns + int(t * 1e9), "SV4", "sod", src, abs(random.gauss(0, 8)),
                            abs(random.gauss(0, 0.01)), 10.0, 0.012])
    if with_observers:  # BOD telemetry: a usable attempt on SV2 and one not usable (no target), 40 samples each
        os.makedirs(os.path.join(run, "bod"), exist_ok=True)
        with open(os.path.join(run, "bod", "SV4.csv"), "w", newline="") as f, \
                open(os.path.join(run, "bod", "SV4_curves.csv"), "w", newline="") as g:
            w, wc = csv.writer(f), csv.writer(g)
            w.writerow(["t_utc", "t_tt_ns", "observer", "attempt", "track", "target", "verdict", "verdict_name",
                        "measurements", "iterations", "residual_rms_arcsec", "correlation_inflation", "a_observer_m",
                        "range_m", "sigma_range_m"] + [f"a_{k}_m" for k in ROE] + [f"sigma_a_{k}_m" for k in ROE]
                       + ["mahalanobis2", "action", "why"])
            wc.writerow(["attempt", "sample", "a_dlambda_m", "residual_rms_arcsec", "chi2", "converged"])
            for n, (hours, usable) in enumerate([(3.0, True), (6.0, False)], start=1):
                est = 50e3 + random.gauss(0, 500)
                w.writerow([f"2024-05-16T0{int(hours)}:00:00.000Z", t0_ns + int(hours * 3600e9), "SV4", n, 0,
                            "SV2" if usable else "", 0 if usable else 4,
                            "usable" if usable else "minimum_at_edge", 100, 3, 3.5, 1.1, 6943000.0, est, 550.0]
                           + [0.0, est, 0.0, 0.0, 0.0, 0.0] + [5.0, 550.0, 5.0, 5.0, 1.0, 20.0]
                           + ["" if n == 2 else 3.2, "SOD initialised from BOD" if usable else "not usable",
                              "" if usable else "the smallest residual is at the nearest sample"])
                for k in range(40):
                    x = 2e3 * 1.1 ** k
                    conv = k > 2
                    res = 3.5 + 80 * abs(math.log(x / est)) if conv else ""
                    wc.writerow([n, k, f"{x:.3f}", res, "" if not conv else res * 10, int(conv)])
    targets = {}
    for tgt, rng in ranges.items():
        targets[tgt] = {"final_range_m": rng, "final_dlambda_error_pct": 0.4 if tgt == "SV2" else -1.1,
                        "final_dlambda_sigma_pct": 1.2 if tgt == "SV2" else 1.4,
                        "convergence_orbits": 1.5 if tgt == "SV2" else 3.0,
                        "frac_within_3sigma": {k: 0.99 for k in ROE},
                        "local_measurements": 240, "remote_measurements": 0 if tgt == "SV2" else 90}
        if nulls:
            targets[tgt] = {k: None for k in targets[tgt]}
    summary = {"scenario": "smoke", "duration_s": 300 * dt, "observers": {"SV4": {"targets": targets}}}
    if not nulls:
        summary["orbits"] = 300 * dt / 5700.0
        summary["observers"]["SV4"]["period_s"] = 5760.0
    with open(os.path.join(run, "summary.json"), "w") as f:
        json.dump(summary, f)

fabricate(os.path.join(work, "full"), True, False)
fabricate(os.path.join(work, "partial"), False, True)
os.makedirs(os.path.join(work, "empty"))
PY
fails=0
check() { [ -s "$1" ] || { echo "FAIL: $1 missing or empty"; fails=$((fails+1)); }; }

"$BIN/artms-report" "$WORK/full" > "$WORK/full.out" 2>&1 || { echo "FAIL: full run exit $?"; cat "$WORK/full.out"; fails=$((fails+1)); }
for f in roe_SV4_SV2.png roe_SV4_SV3.png observer_SV4.png bod_curves_SV4.png bod_range_SV4.png summary.png summary.md; do
  check "$WORK/full/plots/$f"
done
grep -q "PASS" "$WORK/full/plots/summary.md" || { echo "FAIL: no verdict in summary.md"; fails=$((fails+1)); }

"$BIN/artms-report" "$WORK/partial" --out "$WORK/partial_out" > "$WORK/partial.out" 2>&1 \
  || { echo "FAIL: partial run exit $?"; cat "$WORK/partial.out"; fails=$((fails+1)); }
for f in roe_SV4_SV2.png roe_SV4_SV3.png summary.png summary.md; do check "$WORK/partial_out/$f"; done
grep -q "missing: .*observers.csv" "$WORK/partial.out" || { echo "FAIL: missing observers.csv not reported"; fails=$((fails+1)); }
[ ! -e "$WORK/partial_out/observer_SV4.png" ] || { echo "FAIL: observer plot without observers.csv"; fails=$((fails+1)); }

rc=0; "$BIN/artms-report" "$WORK/empty" > "$WORK/empty.out" 2>&1 || rc=$?
[ "$rc" = 1 ] || { echo "FAIL: empty run folder exit $rc, expected 1"; cat "$WORK/empty.out"; fails=$((fails+1)); }
if grep -q Traceback "$WORK"/*.out; then echo "FAIL: traceback"; grep -A20 Traceback "$WORK"/*.out; fails=$((fails+1)); fi

rc=0; "$BIN/artms-report" "$WORK/does_not_exist" > "$WORK/missing.out" 2>&1 || rc=$?
[ "$rc" = 2 ] || { echo "FAIL: missing RUN_DIR exit $rc, expected 2"; fails=$((fails+1)); }

[ "$fails" = 0 ] && echo "report smoke: ok" || { echo "report smoke: $fails failure(s)"; exit 1; }
