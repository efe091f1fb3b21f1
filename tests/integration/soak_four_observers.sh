#!/usr/bin/env bash
# Soak (issue 8, acceptance 3; label soak): config/swarms/soak_four_observers.yaml,
# 4 observers in navigation mode 3 for 24 simulated hours with crosslink
# outages, 10 % message loss and 30 % frame drop-outs. Every process exits 0;
# the resident memory of every process grows by less than 10 % between
# simulated hours 6 and 24 (timing.json rss_kb); every filter is healthy at
# the end (last nav row health 0); the crosslink accounting is exact per link
# (sent = delivered + dropped); the real-time factor is printed.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
SCENARIO=${ARTMS_SOAK_SCENARIO:-$SRC/config/swarms/soak_four_observers.yaml}
DURATION=${ARTMS_SOAK_DURATION:-24h}
rm -rf "$WORK"; mkdir -p "$WORK"
"$BIN/artms-swarm" run "$SCENARIO" --duration "$DURATION" --out "$WORK/run" > "$WORK/swarm.out" 2>&1 \
  || { tail -30 "$WORK/swarm.out"; exit 1; }
/usr/bin/python3 - "$WORK/run" <<'PY'
import csv, json, sys
run = sys.argv[1]
s = json.load(open(f"{run}/summary.json"))
t = json.load(open(f"{run}/timing.json"))
bad = [p for p in s["processes"] if p["exit_code"] != 0]
assert not bad, bad
observers = [p["name"] for p in s["processes"] if p["name"].startswith("observer-")]
assert len(observers) >= 4, observers
hours = t["sim_time_s"] / 3600
print(f"soak: {len(s['processes'])} processes, {hours:.0f} h simulated in {t['wall_time_s']:.0f} s "
      f"(real-time factor {t['real_time_factor']:.0f})")
h_lo = 6 if hours >= 24 else hours / 4
for name, samples in sorted(t["rss_kb"].items()):
    at = dict((int(h), kb) for h, kb in samples)
    lo = at.get(int(h_lo)); hi = at[max(at)]
    growth = (hi - lo) / lo if lo else 0.0
    print(f"  {name:22s} RSS {lo} kB at hour {int(h_lo)} -> {hi} kB at hour {max(at)} ({100 * growth:+.1f} %)")
    assert growth < 0.10, f"{name}: resident memory grew {100 * growth:.1f} % (limit 10 %)"
for o in observers:
    rows = list(csv.DictReader(open(f"{run}/nav/{o[9:]}.csv")))
    assert rows[-1]["health"] == "0", f"{o}: health {rows[-1]['health']} at the end"
isl = s["isl"]
print(f"  isl: sent {isl['sent']}, delivered {isl['delivered']}, dropped {isl['dropped']}")
for link, c in isl.get("per_link", {}).items():
    dropped = sum(c["dropped"].values()) if isinstance(c["dropped"], dict) else c["dropped"]
    assert c["sent"] == c["delivered"] + dropped, (link, c)
tot_dropped = sum(isl["dropped"].values()) if isinstance(isl["dropped"], dict) else isl["dropped"]
assert isl["sent"] == isl["delivered"] + tot_dropped, isl
assert isl["sent"] > 0, "no broadcast sent"
for o, v in s["observers"].items():
    for tgt, r in v.get("targets", {}).items():
        print(f"  {o}->{tgt}: range {r['final_range_m'] / 1e3:.0f} km, dlambda error {r['final_dlambda_error_pct']:.2f} %, "
              f"1-sigma {r['final_dlambda_sigma_pct']:.2f} %, local {r['local_measurements']}, remote {r['remote_measurements']}")
print("soak: ok")
PY
