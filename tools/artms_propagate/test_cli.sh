#!/usr/bin/env bash
# Integration test of the artms-propagate command line: good runs produce CSV
# and OEM; bad arguments give a clear message and a non-zero exit.
set -u
BIN=${ARTMS_PROPAGATE:?}
DIR=${1:?}
mkdir -p "$DIR"
fails=0
check() {  # check NAME EXPECTED_RC EXPECTED_STDERR_FRAGMENT -- args...
  local name=$1 want_rc=$2 want=$3
  shift 4
  "$BIN" "$@" >"$DIR/$name.out" 2>"$DIR/$name.err"
  local rc=$?
  if [ "$want_rc" = "0" ] && [ $rc -ne 0 ]; then
    echo "FAIL $name: exit $rc"; cat "$DIR/$name.err"; fails=$((fails+1)); return
  fi
  if [ "$want_rc" != "0" ] && [ $rc -eq 0 ]; then
    echo "FAIL $name: expected a non-zero exit"; fails=$((fails+1)); return
  fi
  if ! grep -q -- "$want" "$DIR/$name.err"; then
    echo "FAIL $name: stderr lacks '$want':"; cat "$DIR/$name.err"; fails=$((fails+1)); return
  fi
  echo "ok   $name"
}
check oe_run 0 "states over" -- --epoch 2024-05-08T00:00:00Z --oe 6943000,0.0016,99.4,-38,86.4,-239.4 \
  --duration 2h --step 600s --force grav10,drag,sun,moon --out "$DIR/a.csv" --oem "$DIR/a.oem"
[ "$(wc -l < "$DIR/a.csv")" = "14" ] || { echo "FAIL csv rows: $(wc -l < "$DIR/a.csv")"; fails=$((fails+1)); }
head -1 "$DIR/a.csv" | grep -q '^t_utc,t_tt_ns,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps$' || { echo "FAIL csv header"; fails=$((fails+1)); }
grep -q '^CCSDS_OEM_VERS = 2.0$' "$DIR/a.oem" || { echo "FAIL oem header"; fails=$((fails+1)); }
check rv_run 0 "states over" -- --epoch 2024-05-08T00:00:00Z --rv 7000000,0,0,0,7546,0 --duration 10m --step 60s --force two-body --out "$DIR/b.csv"
check no_state 2 "exactly one of --rv or --oe" -- --epoch 2024-05-08T00:00:00Z --out "$DIR/x.csv"
check bad_epoch 2 "invalid UTC time '2024-13-08'" -- --epoch 2024-13-08 --rv 7e6,0,0,0,7546,0 --out "$DIR/x.csv"
check bad_rv 2 "--rv needs 6" -- --epoch 2024-05-08 --rv 7e6,0,0 --out "$DIR/x.csv"
check bad_num 2 "'abc' is not a number" -- --epoch 2024-05-08 --rv 7e6,0,0,abc,7546,0 --out "$DIR/x.csv"
check bad_force 2 "unknown item 'wind'" -- --epoch 2024-05-08 --rv 7e6,0,0,0,7546,0 --force grav10,wind --out "$DIR/x.csv"
check bad_ecc 2 "0 <= e < 1" -- --epoch 2024-05-08 --oe 7e6,1.2,98,0,0,0 --out "$DIR/x.csv"
check bad_duration 2 "invalid duration '-1d'" -- --epoch 2024-05-08 --rv 7e6,0,0,0,7546,0 --duration=-1d --out "$DIR/x.csv"
check bad_mass 2 "mass_kg" -- --epoch 2024-05-08 --rv 7e6,0,0,0,7546,0 --mass 0 --out "$DIR/x.csv"
check both 1 "excludes" -- --epoch 2024-05-08 --rv 7e6,0,0,0,7546,0 --oe 7e6,0,98,0,0,0 --out "$DIR/x.csv"
check missing_out 1 "out is required" -- --epoch 2024-05-08 --rv 7e6,0,0,0,7546,0
echo "$fails failed"
[ $fails -eq 0 ]
