#!/usr/bin/env bash
# Runtime benchmark (issue 15, acceptance 4), not a timed test: the figures
# are printed and written to OUT/runtime_bench.json for the issue notes.
#  1. starling_pse_multi.yaml (3 observers, every frame), 24 simulated hours,
#     seed 7: the DDS multi-process run and the in-process run side by side,
#     wall time and real-time factor of each, and whether the two run folders
#     are byte-identical.
#  2. A 20-seed x 12-orbit campaign of starling_pse.yaml with --jobs 2,
#     in-process (tools/artms_swarm/campaign.py), wall time.
# Usage: bench/runtime_bench.sh [OUT]   (ARTMS_BIN: default build/bin;
# ARTMS_BENCH_SPAN / ARTMS_BENCH_SEEDS / ARTMS_BENCH_ORBITS shorten it).
set -euo pipefail
SRC=$(cd "$(dirname "$0")/.." && pwd)
BIN=${ARTMS_BIN:-$SRC/build/bin}
OUT=${1:-$SRC/build/runtime_bench}
SPAN=${ARTMS_BENCH_SPAN:-24h}
SEEDS=${ARTMS_BENCH_SEEDS:-20}
ORBITS=${ARTMS_BENCH_ORBITS:-12}
export CYCLONEDDS_URI=${CYCLONEDDS_URI:-file://$SRC/config/cyclonedds-loopback.xml}
rm -rf "$OUT"; mkdir -p "$OUT"
now() { date +%s.%N; }
elapsed() { /usr/bin/python3 -c "import sys; print(float(sys.argv[2]) - float(sys.argv[1]))" "$1" "$(now)"; }
for mode in dds in-process; do
  extra=(); [ "$mode" = in-process ] && extra=(--in-process)
  t0=$(now)
  "$BIN/artms-swarm" run "$SRC/config/swarms/starling_pse_multi.yaml" --duration "$SPAN" --seed 7 "${extra[@]}" \
      --out "$OUT/multi-$mode" > "$OUT/multi-$mode.out" 2>&1 || { tail -n 30 "$OUT/multi-$mode.out"; exit 1; }
  elapsed "$t0" > "$OUT/multi-$mode.wall"
done
identical=$(/usr/bin/python3 "$SRC/tests/integration/compare_runs.py" "$OUT/multi-dds" "$OUT/multi-in-process" \
            > "$OUT/compare.txt" 2>&1 && echo true || echo false)
t0=$(now)
/usr/bin/python3 "$SRC/tools/artms_swarm/campaign.py" "$SRC/config/swarms/starling_pse.yaml" --seeds "$SEEDS" \
    --orbits "$ORBITS" --jobs 2 --bin "$BIN" --out "$OUT/campaign" > "$OUT/campaign.out" 2>&1 \
  || { tail -n 30 "$OUT/campaign.out"; exit 1; }
campaign_wall=$(elapsed "$t0")
/usr/bin/python3 - "$OUT" "$SPAN" "$SEEDS" "$ORBITS" "$identical" "$campaign_wall" <<'PY'
import json, sys
out, span, seeds, orbits, identical, campaign_wall = sys.argv[1:]
res = {"multi_span": span, "identical": identical == "true", "campaign_seeds": int(seeds),
       "campaign_orbits": float(orbits), "campaign_jobs": 2, "campaign_wall_s": float(campaign_wall)}
for mode in ("dds", "in-process"):
    t = json.load(open(f"{out}/multi-{mode}/timing.json"))
    res[f"multi_{mode}_wall_s"] = float(open(f"{out}/multi-{mode}.wall").read())
    res[f"multi_{mode}_sim_wall_s"] = t["wall_time_s"]
    res[f"multi_{mode}_real_time_factor"] = t["real_time_factor"]
json.dump(res, open(f"{out}/runtime_bench.json", "w"), indent=2)
print(f"starling_pse_multi.yaml {span}, seed 7 (3 observers):")
for mode in ("dds", "in-process"):
    print(f"  {mode:10s} {res[f'multi_{mode}_wall_s']:7.1f} s wall ({res[f'multi_{mode}_sim_wall_s']:.1f} s simulating, "
          f"{res[f'multi_{mode}_real_time_factor']:.0f}x real time)")
print(f"  run folders byte-identical: {res['identical']}")
print(f"campaign starling_pse.yaml, {seeds} seeds x {orbits} orbits, --jobs 2: {res['campaign_wall_s']:.0f} s wall")
PY
