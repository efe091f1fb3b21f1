#!/usr/bin/env bash
# Issue 17 / docs/bod.md: health check 1 does not take a BOD estimate whose
# mean J2 model misses the target's motion. The world sweep's drag_area_2x
# case (420 km, SV2's truth drag area doubled), 4.5 orbits, seed 7:
#  1. with the default tuning.bod.max_fit_ratio (1.5): BOD's post-fit RMS is
#     1.6-3.0 x what it should be (IMP's 1-sigma and BOD's expected 2"
#     misfit in quadrature), each attempt is reported "not used for health
#     check 1" (before health check 5 flags SV2 at 03:44 and the first
#     batch after it), SOD is never re-initialised from BOD, and SV2's a*dlambda
#     ends within 1 % of range and within 3 sigma;
#  2. with the gate open (max_fit_ratio 100) the same run re-initialises SV2
#     from BOD (the failure the gate prevents: the BOD range is ~10 % long).
# The base is starling_pse_flight_exact_clock.yaml: a filter that trusts the
# camera clock knows SV2's range to ~0.1 %, so check 1 takes BOD's ~10 %
# error for a divergence. With the shipped clock residual estimated (~1 %)
# the open gate's BOD estimates pass check 1 and SV2 is never re-initialised
# (stop 42: 0.704 % at 1.122 % with the gate; the same run open, no re-initialisation).
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
PY=/usr/bin/python3
"$PY" "$SRC/tools/artms_swarm/world_sweep.py" --base "$SRC/config/swarms/starling_pse_flight_exact_clock.yaml" --bin "$BIN" \
  --dry-run --out "$WORK/dry" > "$WORK/dry.out" 2>&1 || { cat "$WORK/dry.out"; exit 1; }
"$PY" - "$WORK/dry/drag_area_2x.yaml" "$WORK/open.yaml" <<'PY'
import sys, yaml
class Loader(yaml.SafeLoader):  # keep the epoch a string, as the scenario has it
    pass
Loader.yaml_implicit_resolvers = {k: [r for r in v if r[0] != "tag:yaml.org,2002:timestamp"]
                                  for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
s = yaml.load(open(sys.argv[1]), Loader=Loader)
s.setdefault("tuning", {}).setdefault("bod", {})["max_fit_ratio"] = 100
yaml.safe_dump(s, open(sys.argv[2], "w"), sort_keys=False)
PY
for v in gate:"$WORK/dry/drag_area_2x.yaml" open:"$WORK/open.yaml"; do
  name=${v%%:*}; yaml=${v#*:}
  "$BIN/artms-swarm" run "$yaml" --seed 7 --orbits 4.5 --in-process --no-report --out "$WORK/$name" \
    > "$WORK/$name.out" 2>&1 || { echo "FAIL: $name run"; tail "$WORK/$name.out"; exit 1; }
done
"$PY" - "$WORK" <<'PY'
import json, sys
w = sys.argv[1]
gate = open(f"{w}/gate/events.log").read()
opened = open(f"{w}/open/events.log").read()
n_skipped = gate.count("not used for health check 1 of target SV2")
print(f"gate: {n_skipped} BOD estimates not used for health check 1 of SV2")
assert n_skipped >= 2, gate
assert "SV2 re-initialised from BOD" not in gate and "SV2 unhealthy (health check 1" not in gate, gate
t = json.load(open(f"{w}/gate/summary.json"))["observers"]["SV4"]["targets"]["SV2"]
err, sig = t["final_dlambda_error_pct"], t["final_dlambda_sigma_pct"]
print(f"gate: SV2 final a*dlambda error {err:.3f} % of range, 1-sigma {sig:.3f} %")
assert abs(err) <= 1.0 and abs(err) <= 3.0 * sig, (err, sig)
assert "SV2 re-initialised from BOD" in opened or "SV2 unhealthy (health check 1" in opened, opened
assert "not used for health check 1" not in opened, opened
t = json.load(open(f"{w}/open/summary.json"))["observers"]["SV4"]["targets"]["SV2"]
print(f"gate open: SV2 re-initialised from BOD; final a*dlambda error {t['final_dlambda_error_pct']:.3f} % "
      f"(1-sigma {t['final_dlambda_sigma_pct']:.3f} %)")
PY
echo "bod_fit_gate: ok"
