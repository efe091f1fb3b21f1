#!/usr/bin/env bash
# Issue 15, acceptance 5: the installable build. Installs the build into
# $WORK/prefix, then, with nothing pointing back at the source or build trees
# (ARTMS_DATA_DIR, ARTMS_CONFIG_DIR and CYCLONEDDS_URI unset):
# - builds tests/install_consumer (find_package(artms), artms::fsw) against
#   the install and runs it: it must find <prefix>/share/artms/data through
#   the install prefix and navigate on GNSS;
# - runs the installed artms-swarm (validate, a 0.2-orbit run --in-process and
#   a short DDS run) in a temporary folder outside the source and build
#   trees; the in-process run folder must be byte-identical to the build
#   tree's (all files but timing.json and logs/).
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; BUILD=${ARTMS_BUILD_DIR:?}; WORK=${1:?}
CMAKE=${ARTMS_CMAKE:-cmake}
rm -rf "$WORK"; mkdir -p "$WORK"
PREFIX=$WORK/prefix
unset ARTMS_DATA_DIR ARTMS_CONFIG_DIR CYCLONEDDS_URI
fail() { echo "FAIL: $*"; exit 1; }

# 1. Install.
"$CMAKE" --install "$BUILD" --prefix "$PREFIX" > "$WORK/install.log" 2>&1 \
  || { tail -n 30 "$WORK/install.log"; fail "cmake --install"; }
for f in bin/artms-swarm bin/artms-truth bin/artms-observer bin/artms-camera-renderer \
         bin/artms-crosslink-emulator bin/artms-recorder bin/artms-imp bin/artms-render \
         bin/artms-propagate bin/artms-sod-replay bin/artms-report; do
  [ -x "$PREFIX/$f" ] || fail "$f not installed (or not executable)"
done
for f in share/artms/data/gravity/GGM01S.gfc share/artms/data/stars/bsc5.dat \
         share/artms/config/cyclonedds-loopback.xml share/artms/config/cameras/nst.yaml \
         share/artms/config/swarms/starling_pse.yaml include/artms/fsw/observer.hpp \
         include/artms/io/paths.hpp; do
  [ -f "$PREFIX/$f" ] || fail "$f not installed"
done
config=$(find "$PREFIX" -name artmsConfig.cmake | head -n 1)
[ -n "$config" ] || fail "no artmsConfig.cmake under $PREFIX"
for f in artmsConfigVersion.cmake artmsTargets.cmake; do
  [ -f "$(dirname "$config")/$f" ] || fail "no $f beside $config"
done
echo "installed: $(find "$PREFIX" -type f | wc -l) files, package config ${config#"$PREFIX"/}"

# 2. The consumer project, configured against the install only.
"$CMAKE" -S "$SRC/tests/install_consumer" -B "$WORK/consumer-build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$PREFIX" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF > "$WORK/consumer-configure.log" 2>&1 \
  || { tail -n 30 "$WORK/consumer-configure.log"; fail "configuring the consumer"; }
grep -q "artms_DIR:PATH=$PREFIX/" "$WORK/consumer-build/CMakeCache.txt" \
  || fail "find_package(artms) did not find the install: $(grep artms_DIR "$WORK/consumer-build/CMakeCache.txt")"
"$CMAKE" --build "$WORK/consumer-build" > "$WORK/consumer-build.log" 2>&1 \
  || { tail -n 40 "$WORK/consumer-build.log"; fail "building the consumer"; }
if grep -E -q "$SRC/common|$BUILD/common" "$WORK/consumer-build/build.ninja"; then
  fail "the consumer's build uses the source or build tree: $(grep -E -o "($SRC|$BUILD)/common[^ ]*" "$WORK/consumer-build/build.ninja" | sort -u | head -n 3)"
fi
"$CMAKE" --install "$WORK/consumer-build" --prefix "$PREFIX" > /dev/null

# Installed beside the programs, with no environment: the data of the prefix.
out=$("$PREFIX/bin/artms_install_consumer") || { echo "$out"; fail "installed consumer exited $?"; }
grep -qx "data: $PREFIX/share/artms/data" <<<"$out" || { echo "$out"; fail "installed consumer used other data"; }
grep -qx "navigation source: gnss" <<<"$out" || { echo "$out"; fail "installed consumer does not navigate on GNSS"; }
echo "consumer (installed, no environment): $(tail -n 1 <<<"$out"), $(head -n 1 <<<"$out")"
# From its build folder, pointed at the install by the environment.
out=$(ARTMS_DATA_DIR="$PREFIX/share/artms/data" "$WORK/consumer-build/artms_install_consumer") \
  || { echo "$out"; fail "consumer with ARTMS_DATA_DIR exited $?"; }
grep -qx "navigation source: gnss" <<<"$out" || { echo "$out"; fail "consumer with ARTMS_DATA_DIR: no GNSS"; }
echo "consumer (build folder, ARTMS_DATA_DIR): $(tail -n 1 <<<"$out")"
# From its build folder with no environment: the configured install prefix,
# or an error naming every place tried.
configured=$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$BUILD/CMakeCache.txt")
if [ -f "$configured/share/artms/data/gravity/GGM01S.gfc" ]; then
  out=$("$WORK/consumer-build/artms_install_consumer") || { echo "$out"; fail "consumer (configured prefix) exited $?"; }
  grep -qx "data: $configured/share/artms/data" <<<"$out" || { echo "$out"; fail "consumer did not use $configured"; }
  echo "consumer (build folder, no environment): found $configured/share/artms/data"
else
  rc=0; err=$("$WORK/consumer-build/artms_install_consumer" 2>&1) || rc=$?
  [ "$rc" = 2 ] || { echo "$err"; fail "consumer without data: exit $rc, expected 2"; }
  for part in "ARTMS_DATA_DIR (not set)" "$WORK/share/artms/data (beside the executable" \
              "$configured/share/artms/data (the install prefix)"; do
    grep -qF "$part" <<<"$err" || { echo "$err"; fail "the error does not name '$part'"; }
  done
  echo "consumer (build folder, no environment): refused, naming the 3 places tried"
fi

# 3. The installed programs, from a folder outside the source and build trees.
TMP=$(mktemp -d "${TMPDIR:-/tmp}/artms-install-XXXXXX")
trap 'rm -rf "$TMP"' EXIT
case "$TMP" in "$SRC"/*|"$BUILD"/*) fail "temporary folder $TMP is inside the source or build tree";; esac
cd "$TMP"
SCENARIO=$PREFIX/share/artms/config/swarms/starling_pse.yaml
"$PREFIX/bin/artms-swarm" validate "$SCENARIO" > validate.out 2>&1 || { cat validate.out; fail "installed validate"; }
echo "installed artms-swarm validate: $(tail -n 1 validate.out)"
"$PREFIX/bin/artms-swarm" run "$SCENARIO" --orbits 0.2 --seed 7 --in-process --out inproc > inproc.out 2>&1 \
  || { tail -n 30 inproc.out; tail -n 20 inproc/logs/*.log; fail "installed run --in-process"; }
grep -q "artms-report failed" inproc.out && { cat inproc/logs/report.log; fail "installed artms-report failed"; }
[ -n "$(ls -A inproc/plots 2>/dev/null)" ] || fail "installed artms-report made no plots"
"$PREFIX/bin/artms-swarm" run "$SCENARIO" --orbits 0.1 --seed 7 --out dds > dds.out 2>&1 \
  || { tail -n 30 dds.out; tail -n 20 dds/logs/*.log; fail "installed run (DDS)"; }
/usr/bin/python3 - dds/summary.json <<'PY' || fail "a process of the installed DDS run failed"
import json, sys
bad = [p for p in json.load(open(sys.argv[1]))["processes"] if p["exit_code"] != 0]
print(f"installed DDS run: {'ok' if not bad else bad}")
sys.exit(1 if bad else 0)
PY
# The same in-process run with the build tree's programs: the same bytes.
"$BIN/artms-swarm" run "$SCENARIO" --orbits 0.2 --seed 7 --in-process --out build-tree > build-tree.out 2>&1 \
  || { tail -n 30 build-tree.out; fail "build-tree run --in-process"; }
echo -n "installed vs build-tree run folder: "
/usr/bin/python3 "$SRC/tests/integration/compare_runs.py" inproc build-tree
echo "install consumer: ok"
