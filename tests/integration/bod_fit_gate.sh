#!/usr/bin/env bash
# Issue 17 / docs/bod.md: health check 1 does not take a BOD estimate whose
# mean J2 model misses the target's motion. The world sweep's drag_area_2x
# case (420 km, SV2's truth drag area doubled), 4.5 orbits, seed 7:
#  1. as shipped (SOD estimates SV2's differential ballistic coefficient and
#     BOD's model correction propagates SV2 with it, stop 44): every BOD
#     estimate of SV2 fits and passes health check 1, SOD is never
#     re-initialised from BOD, and SV2's a*dlambda ends within 1 % of range
#     and within 3 sigma (stop 44: 0.24 % at 0.38 %);
#  2. with the ballistic state off, BOD's model misses SV2's drag (post-fit
#     RMS ~2 x what it should be): with the default tuning.bod.max_fit_ratio
#     (1.5) each attempt is reported "not used for health check 1" and SOD
#     is never re-initialised from BOD (SOD's own estimate is then wrong
#     too: this world's drag is what the ballistic state is for);
#  3. the same with the gate open (max_fit_ratio 100) re-initialises SV2
#     from BOD (the failure the gate prevents).
# The base is starling_pse_flight_exact_clock.yaml: a filter that trusts the
# camera clock knows SV2's range to ~0.1 %, so check 1 takes BOD's error for
# a divergence.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
PY=/usr/bin/python3
"$PY" "$SRC/tools/artms_swarm/world_sweep.py" --base "$SRC/config/swarms/starling_pse_flight_exact_clock.yaml" --bin "$BIN" \
  --dry-run --out "$WORK/dry" > "$WORK/dry.out" 2>&1 || { cat "$WORK/dry.out"; exit 1; }
"$PY" - "$WORK/dry/drag_area_2x.yaml" "$WORK/gate.yaml" "$WORK/open.yaml" <<'PY'
import sys, yaml
class Loader(yaml.SafeLoader):  # keep the epoch a string, as the scenario has it
    pass
Loader.yaml_implicit_resolvers = {k: [r for r in v if r[0] != "tag:yaml.org,2002:timestamp"]
                                  for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
s = yaml.load(open(sys.argv[1]), Loader=Loader)
assert s["tuning"]["sod"]["ballistic"]["estimate"] is True, s["tuning"]["sod"]
s["tuning"]["sod"]["ballistic"] = {"estimate": False}
yaml.safe_dump(s, open(sys.argv[2], "w"), sort_keys=False)
s["tuning"].setdefault("bod", {})["max_fit_ratio"] = 100
yaml.safe_dump(s, open(sys.argv[3], "w"), sort_keys=False)
PY
for v in learnt:"$WORK/dry/drag_area_2x.yaml" gate:"$WORK/gate.yaml" open:"$WORK/open.yaml"; do
  name=${v%%:*}; yaml=${v#*:}
  "$BIN/artms-swarm" run "$yaml" --seed 7 --orbits 4.5 --in-process --no-report --out "$WORK/$name" \
    > "$WORK/$name.out" 2>&1 || { echo "FAIL: $name run"; tail "$WORK/$name.out"; exit 1; }
done
"$PY" - "$WORK" <<'PY'
import csv, json, sys
w = sys.argv[1]
def sv2_attempts(name):
    return [r for r in csv.DictReader(open(f"{w}/{name}/bod/SV4.csv")) if r["target"] == "SV2"]
def reinitialised(log):
    return "SV2 re-initialised from BOD" in log or "SV2 unhealthy (health check 1" in log
learnt = open(f"{w}/learnt/events.log").read()
a = sv2_attempts("learnt")
print("learnt: SV2 BOD attempts " + ", ".join(f"{r['residual_rms_arcsec']}\" d2 {r['mahalanobis2']} ({r['action']})" for r in a))
assert len(a) >= 2 and all(r["action"] == "health check 1 passed" for r in a), a
assert not reinitialised(learnt), learnt
t = json.load(open(f"{w}/learnt/summary.json"))["observers"]["SV4"]["targets"]["SV2"]
err, sig = t["final_dlambda_error_pct"], t["final_dlambda_sigma_pct"]
print(f"learnt: SV2 final a*dlambda error {err:.3f} % of range, 1-sigma {sig:.3f} %")
assert abs(err) <= 1.0 and abs(err) <= 3.0 * sig, (err, sig)
gate = open(f"{w}/gate/events.log").read()
opened = open(f"{w}/open/events.log").read()
n_skipped = gate.count("not used for health check 1 of target SV2")
print(f"gate (ballistic state off): {n_skipped} BOD estimates not used for health check 1 of SV2")
assert n_skipped >= 2, gate
assert not reinitialised(gate), gate
assert reinitialised(opened), opened
assert "not used for health check 1" not in opened, opened
print("gate open: SV2 re-initialised from BOD")
PY
echo "bod_fit_gate: ok"
