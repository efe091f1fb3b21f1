#!/usr/bin/env bash
# Issue 15: the campaign runner (tools/artms_swarm/campaign.py) on
# starling_pse.yaml, 3 seeds x 0.5 orbits, 2 at a time: campaign_summary.json
# has every observer/target of the runs over 3 seeds and its plots; a second
# call reuses the 3 seed folders; a changed scenario file (one comment line)
# makes all 3 stale and runs them again (same results); the same campaign on a
# Dask LocalCluster of 2 workers on 127.0.0.1 gives byte-identical per-seed
# summary.json files and the same campaign_summary.json; a failing seed is
# recorded (exit code, output tail), the campaign goes on and exits 1.
# replay_campaign.py replays the three seeds (and records a refused option).
# Then the unit test of tools/python/artms_tools on one seed folder.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
PY=/usr/bin/python3
CAMPAIGN="$SRC/tools/artms_swarm/campaign.py"
cp "$SRC/config/swarms/starling_pse.yaml" "$WORK/pse.yaml"
common=(--seeds 3 --orbits 0.5 --bin "$BIN")

campaign() {  # campaign NAME ARGS...: stdout/stderr in $WORK/NAME.out/.err, fails the test on a non-zero exit
  local name=$1; shift
  "$PY" "$CAMPAIGN" "$@" > "$WORK/$name.out" 2> "$WORK/$name.err" \
    || { echo "FAIL: campaign $name exit $?"; cat "$WORK/$name.out" "$WORK/$name.err"; exit 1; }
}
count() { grep -c -- "$1" "$2" || true; }

# 1. Three seeds, two at a time.
start=$(date +%s%N)
campaign first "$WORK/pse.yaml" "${common[@]}" --jobs 2 --out "$WORK/local"
echo "3 seeds, --jobs 2: $(( ($(date +%s%N) - start) / 1000000 )) ms"
cat "$WORK/first.out"
grep -q "WARNING: .*--in-process" "$WORK/first.err" && echo "(artms-swarm has no --in-process yet: DDS runs)"
"$PY" - "$WORK/local" <<'PY'
import json, os, sys
d = sys.argv[1]
c = json.load(open(f"{d}/campaign_summary.json"))
assert c["seeds"] == [1, 2, 3] and c["runs"] == 3 and c["failures"] == [], (c["seeds"], c["failures"])
pairs = set()
for s in c["seeds"]:
    j = json.load(open(f"{d}/seed_{s}/summary.json"))
    pairs |= {f"{o}/{t}" for o, od in j["observers"].items() for t in od.get("targets", {})}
assert pairs and pairs == set(c["targets"]), (pairs, set(c["targets"]))
for k, t in c["targets"].items():
    obs, tgt = k.split("/")
    assert t["runs"] == 3 and len(t["convergence_orbits"]) == 3, k
    for key in ("frac_inside_band", "frac_inside_band_after_median", "mean_nees_after", "steps"):
        assert key in t, (k, key)
    assert len(t["final_dlambda_error_pct"]["per_seed"]) == 3 and t["final_dlambda_error_pct"]["max"] is not None, k
    assert len(t["frac_within_3sigma"]["per_seed"]) == 3, k
    if t["frac_inside_band"] is not None:
        assert abs(t["frac_inside_band"] + t["frac_below_band"] + t["frac_above_band"] - 1.0) < 1e-9, (k, t)
    beyond3 = [json.load(open(f"{d}/seed_{s}/summary.json"))["observers"][obs]["targets"][tgt].get("frac_beyond_3sigma")
               for s in c["seeds"]]
    beyond3 = [v for v in beyond3 if v is not None]
    assert t["worst_seed_frac_beyond_3sigma"] == (max(beyond3) if beyond3 else None), (k, t["worst_seed_frac_beyond_3sigma"])
    healthy5 = [json.load(open(f"{d}/seed_{s}/summary.json"))["observers"][obs]["targets"][tgt]
                .get("longest_beyond_5sigma_reported_healthy_orbits") for s in c["seeds"]]
    w = t["worst_seed_beyond_5sigma_reported_healthy"]
    assert (w is None) == all(v is None for v in healthy5), (k, w, healthy5)
    assert w is None or w["orbits"] == max(v for v in healthy5 if v is not None), (k, w, healthy5)
    assert t["convergence"]["never_converged"] == sum(v is None for v in t["convergence"]["per_seed"]), k
    for png in (f"campaign_nees_{obs}_{tgt}.png", f"campaign_error_{obs}_{tgt}.png"):
        assert os.path.getsize(f"{d}/{png}") > 0, png
assert "chi2(2N)" in c["nis_note"], c["nis_note"]
with_nis = 0
for k, t in c["targets"].items():
    n = t["nis"]["after_median_convergence"] if t.get("nis") else None
    if n is None:
        continue  # no bearing of this target in the window (0.5 orbits)
    assert n["updates"] > 0 and 0.0 <= n["frac_inside_band"] <= 1.0 and n["mean_nis"] > 0, (k, n)
    with_nis += 1
assert with_nis >= 1, {k: t.get("nis") for k, t in c["targets"].items()}
for k, t in c["targets"].items():
    cm = t.get("common_to_every_seed")
    if cm is None:
        continue
    assert cm["roe"] == ["da", "dlambda", "dex", "dey", "dix", "diy"] and len(cm["ratio_to_independent"]) == 6, (k, cm)
    assert all(x >= 0 for x in cm["rms_seed_mean_z"] + cm["rms_z"]), (k, cm)
with_directions = 0
for k, t in c["targets"].items():
    bd = t.get("by_direction")
    if not bd or "mean_z2_per_principal_direction" not in bd:
        continue
    p, z = bd["mean_z2_per_principal_direction"], bd["mean_z2_per_roe"]
    assert len(p) == 6 and len(z) == 6 and bd["principal_steps"] > 0, (k, bd)
    # The six directions' squares sum to the NEES, which the covariance's ROE axes share.
    assert all(x >= 0 for x in p + z) and sum(p) > 0, (k, bd)
    with_directions += 1
assert with_directions >= 1, {k: t.get("by_direction") for k, t in c["targets"].items()}
import math
with_spread = 0
for k, t in c["targets"].items():
    sp = t.get("nees_spread")
    if sp is None:
        continue
    assert sp["variance_of_average"] >= 0 and sp["variance_with_runs_shifted"] >= 0, (k, sp)
    assert abs(sp["common_sd"] - math.sqrt(max(sp["variance_of_average"] - sp["variance_with_runs_shifted"], 0.0))) < 1e-9, (k, sp)
    with_spread += 1
assert with_spread >= 1, {k: t.get("nees_spread") for k, t in c["targets"].items()}
# Oracle: per step, the principal directions' squares (numpy's eigenvectors of nav/targets.csv's
# covariance) sum to the evaluation's NEES (C++, eval/targets.csv).
sys.path.insert(0, os.path.join(os.environ["ARTMS_SOURCE_DIR"], "tools", "python"))
from artms_tools.runfolder import target_nees, target_principal_errors
import math
checked = 0
for s in c["seeds"]:
    nees, pz = target_nees(f"{d}/seed_{s}"), target_principal_errors(f"{d}/seed_{s}")
    for k, series in pz.items():
        for t, z2 in series.items():
            n = nees[k].get(t)
            if n is None or not math.isfinite(n):
                continue
            assert abs(sum(z2) - n) <= 1e-3 + 1e-2 * n, (s, k, t, sum(z2), n)
            checked += 1
assert checked > 0
print(f"principal directions: {checked} steps, their squares sum to the evaluation's NEES")
for s in c["seeds"]:
    r = json.load(open(f"{d}/seed_{s}/campaign_run.json"))
    assert r["seed"] == s and r["span"] == {"orbits": 0.5} and len(r["scenario_sha256"]) == 64, r
print("campaign summary:", ", ".join(f"{k} {t['runs']} runs" for k, t in c["targets"].items()))
PY
# The common-error diagnostic on synthetic runs: independent errors give a
# ratio near 1, an error shared by every run a ratio near sqrt(runs).
"$PY" - "$CAMPAIGN" <<'PY'
import math, os, sys
import numpy as np
sys.path.insert(0, os.path.dirname(sys.argv[1]))
import campaign
rng = np.random.default_rng(5)
R, T = 16, 4000
times = list(range(T))
sel = np.ones(T, bool)
indep = [{t: list(rng.standard_normal(6)) for t in times} for _ in range(R)]
shared = rng.standard_normal((T, 6))
common = [{t: list(0.9 * shared[t] + 0.1 * rng.standard_normal(6)) for t in times} for _ in range(R)]
a = campaign.common_mode_entry(indep, times, sel)["ratio_to_independent"]
b = campaign.common_mode_entry(common, times, sel)["ratio_to_independent"]
assert all(0.9 < x < 1.1 for x in a), a
assert all(0.9 * math.sqrt(R) < x < 1.05 * math.sqrt(R) for x in b), b
print(f"common-error diagnostic: independent runs x {min(a):.2f}-{max(a):.2f}, shared error x {min(b):.2f}-{max(b):.2f} "
      f"(sqrt({R}) = {math.sqrt(R):.2f})")
PY
for s in 1 2 3; do cp "$WORK/local/seed_$s/summary.json" "$WORK/summary_$s.json"; done

# replay_campaign.py on the three seeds: every seed replayed by
# artms-sod-replay, band statistics per target; a replay option the replay
# refuses fails every seed: recorded, exit 1.
REPLAY="$SRC/tools/artms_swarm/replay_campaign.py"
"$PY" "$REPLAY" "$WORK/local" --out "$WORK/replay" --bin "$BIN" --after-orbit 0 > "$WORK/replay.out" 2> "$WORK/replay.err" \
  || { echo "FAIL: replay_campaign exit $?"; cat "$WORK/replay.out" "$WORK/replay.err"; exit 1; }
cat "$WORK/replay.out"
set +e
"$PY" "$REPLAY" "$WORK/local" --out "$WORK/replay_bad" --bin "$BIN" -- --adaptive-form bogus \
  > "$WORK/replay_bad.out" 2> "$WORK/replay_bad.err"
rc=$?
set -e
[ "$rc" = 1 ] || { echo "replay_campaign with a refused option: exit $rc, expected 1"; cat "$WORK/replay_bad.err"; exit 1; }
"$PY" - "$WORK" <<'PY'
import json, sys
w = sys.argv[1]
r = json.load(open(f"{w}/replay/replay_summary.json"))
assert r["seeds"] == [1, 2, 3] and r["failures"] == [], r
stats = [t for t in r["targets"].values() if t]
assert stats, r["targets"]
for t in stats:
    assert t["runs"] == 3 and t["steps"] > 0 and t["mean_nees"] > 0, t
    assert abs(t["frac_inside_band"] + t["frac_above_band"] + t["frac_below_band"] - 1.0) < 1e-9, t
    assert len(t["mean_z2_per_roe"]) == 6 and all(z >= 0 for z in t["mean_z2_per_roe"]), t
    d = t["mean_z2_per_principal_direction"]
    assert len(d) == 6 and abs(sum(d) - t["mean_nees"]) <= 0.01 * t["mean_nees"], t  # the csv rounds the errors
bad = json.load(open(f"{w}/replay_bad/replay_summary.json"))
assert bad["seeds"] == [] and [f["seed"] for f in bad["failures"]] == [1, 2, 3], bad
assert all(f["exit_code"] not in (0, None) and f["output_tail"] for f in bad["failures"]), bad["failures"]
print(f"replay_campaign: {len(stats)} targets over 3 replayed seeds; a refused option: 3 failures recorded, exit 1")
PY

# 2. The same call again: every seed reused, nothing run.
campaign again "$WORK/pse.yaml" "${common[@]}" --jobs 2 --out "$WORK/local"
[ "$(count ': reused seed_' "$WORK/again.err")" = 3 ] || { echo "FAIL: seeds not reused"; cat "$WORK/again.err"; exit 1; }
[ "$(count ' started$' "$WORK/again.err")" = 0 ] || { echo "FAIL: a seed ran again"; cat "$WORK/again.err"; exit 1; }
cmp "$WORK/first.out" "$WORK/again.out" || { echo "FAIL: another summary from reused seeds"; exit 1; }

# 3. A comment line changes the scenario's bytes: every seed is stale and runs again.
echo "# campaign test: this comment changes the file's sha256" >> "$WORK/pse.yaml"
campaign edited "$WORK/pse.yaml" "${common[@]}" --jobs 2 --out "$WORK/local"
[ "$(count 'is stale (.*the scenario file changed' "$WORK/edited.err")" = 3 ] \
  || { echo "FAIL: edited scenario did not make the seeds stale"; cat "$WORK/edited.err"; exit 1; }
[ "$(count ' finished in ' "$WORK/edited.err")" = 3 ] || { echo "FAIL: seeds not re-run"; cat "$WORK/edited.err"; exit 1; }
for s in 1 2 3; do cmp "$WORK/summary_$s.json" "$WORK/local/seed_$s/summary.json" \
  || { echo "FAIL: seed $s gave another summary.json after a comment-only change"; exit 1; }; done

# 4. The same campaign on a Dask LocalCluster (2 workers, loopback).
start=$(date +%s%N)
campaign dask "$WORK/pse.yaml" "${common[@]}" --dask-local 2 --out "$WORK/dask"
echo "3 seeds, --dask-local 2: $(( ($(date +%s%N) - start) / 1000000 )) ms"
grep -q "LocalCluster at tcp://127.0.0.1:" "$WORK/dask.err" || { echo "FAIL: cluster not on 127.0.0.1"; cat "$WORK/dask.err"; exit 1; }
for s in 1 2 3; do cmp "$WORK/local/seed_$s/summary.json" "$WORK/dask/seed_$s/summary.json" \
  || { echo "FAIL: seed $s: Dask and local summary.json differ"; exit 1; }; done
cmp "$WORK/local/campaign_summary.json" "$WORK/dask/campaign_summary.json" \
  || { echo "FAIL: Dask and local campaign_summary.json differ"; exit 1; }

# 5. A failing seed: recorded, the others go on, exit 1.
mkdir -p "$WORK/failbin"
cat > "$WORK/failbin/artms-swarm" <<EOF
#!/usr/bin/env bash
case " \$* " in *" --seed 4 "*) echo "injected failure for seed 4" >&2; exit 3;; esac
exec "$BIN/artms-swarm" "\$@"
EOF
chmod +x "$WORK/failbin/artms-swarm"
rc=0
"$PY" "$CAMPAIGN" "$WORK/pse.yaml" --seeds 2 --first-seed 3 --orbits 0.5 --bin "$WORK/failbin" --out "$WORK/local" \
  > "$WORK/fail.out" 2> "$WORK/fail.err" || rc=$?
[ "$rc" = 1 ] || { echo "FAIL: campaign with a failed seed exit $rc, expected 1"; cat "$WORK/fail.err"; exit 1; }
grep -q "seed 4 FAILED" "$WORK/fail.err" || { echo "FAIL: failure not reported"; cat "$WORK/fail.err"; exit 1; }
"$PY" - "$WORK/local/campaign_summary.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
assert c["seeds"] == [3] and c["seeds_requested"] == [3, 4], c["seeds"]
f = c["failures"]
assert len(f) == 1 and f[0]["seed"] == 4 and f[0]["exit_code"] == 3, f
assert any("injected failure for seed 4" in line for line in f[0]["output_tail"]), f
PY

# 6. The shared Python module, on one seed folder.
"$PY" "$SRC/tests/integration/python_tools_test.py" "$WORK/local/seed_1"
echo "campaign: ok"
