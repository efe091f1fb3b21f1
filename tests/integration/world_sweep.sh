#!/usr/bin/env bash
# Issue 17: the world sweep (tools/artms_swarm/world_sweep.py). Its unit test
# (edits, YAML, health events, the verdict on made-up run folders), then on
# starling_pse_flight.yaml: --dry-run writes and validates all 13 variants; a
# sweep of two cases x 0.3 orbits, 2 at a time, gives one row per case and
# target with a PASS/FAIL verdict (world_sweep.md, world_sweep.json); the same
# call again reuses both run folders and gives the same bytes.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
PY=/usr/bin/python3
SWEEP="$SRC/tools/artms_swarm/world_sweep.py"
BASE="$SRC/config/swarms/starling_pse_flight.yaml"

"$PY" "$SRC/tests/integration/world_sweep_test.py"

"$PY" "$SWEEP" --base "$BASE" --bin "$BIN" --dry-run --out "$WORK/dry" > "$WORK/dry.out" 2> "$WORK/dry.err" \
  || { echo "FAIL: --dry-run exit $?"; cat "$WORK/dry.out" "$WORK/dry.err"; exit 1; }
[ "$(ls "$WORK"/dry/*.yaml | wc -l)" = 13 ] || { echo "FAIL: not 13 variants"; ls "$WORK/dry"; exit 1; }
grep -q "^13 of 13 variants valid" "$WORK/dry.out" || { echo "FAIL: variants"; cat "$WORK/dry.out" "$WORK/dry.err"; exit 1; }

sweep() {  # sweep NAME: stdout/stderr in $WORK/NAME.out/.err
  "$PY" "$SWEEP" --base "$BASE" --bin "$BIN" --cases flight,tag_plus_0.05 --orbits 0.3 --settle-orbits 0.1 \
    --jobs 2 --out "$WORK/sweep" > "$WORK/$1.out" 2> "$WORK/$1.err" \
    || { echo "FAIL: sweep $1 exit $?"; cat "$WORK/$1.out" "$WORK/$1.err"; exit 1; }
}
sweep first
cat "$WORK/first.out"
"$PY" - "$WORK/sweep" <<'PY'
import json, sys
d = sys.argv[1]
j = json.load(open(f"{d}/world_sweep.json"))
assert [c["name"] for c in j["cases"]] == ["flight", "tag_plus_0.05"] and all(c["problem"] is None for c in j["cases"]), j["cases"]
pairs = {}
for r in j["rows"]:
    assert r["verdict"] in ("PASS", "FAIL"), r
    for k in ("final_dlambda_error_pct", "final_dlambda_sigma_pct", "final_max_error_over_sigma",
              "longest_beyond_5sigma_orbits"):
        assert isinstance(r[k], float), (k, r)
    pairs.setdefault(r["case"], set()).add(f"{r['observer']}/{r['target']}")
for c in ("flight", "tag_plus_0.05"):
    s = json.load(open(f"{d}/{c}/summary.json"))
    want = {f"{o}/{t}" for o, od in s["observers"].items() for t in od.get("targets", {})}
    assert want and pairs.get(c) == want, (c, pairs.get(c), want)
assert j["counts"]["PASS"] + j["counts"]["FAIL"] == len(j["rows"]), j["counts"]
md = open(f"{d}/world_sweep.md").read()
assert md.count("| flight |") == len(pairs["flight"]) and "PASS" in md + "FAIL", md
PY
grep -q "^PASS [0-9]*, FAIL [0-9]*$" "$WORK/first.out" || { echo "FAIL: no count line"; exit 1; }
cp "$WORK/sweep/world_sweep.json" "$WORK/first.json"

sweep again
[ "$(grep -c 'run folder reused' "$WORK/again.err" || true)" = 2 ] || { echo "FAIL: not reused"; cat "$WORK/again.err"; exit 1; }
cmp "$WORK/first.out" "$WORK/again.out" && cmp "$WORK/first.json" "$WORK/sweep/world_sweep.json" \
  || { echo "FAIL: another table from the same run folders"; exit 1; }
echo "world_sweep: ok"
