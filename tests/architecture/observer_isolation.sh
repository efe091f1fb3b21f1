#!/usr/bin/env bash
# Observers never read truth (DESIGN.md section 2): the observer binary must
# not link the truth propagator, SUNDIALS or the renderer. Checks the link
# line CMake generated for artms-observer.
set -euo pipefail
BUILD=${1:?}
line=$(awk '/^build bin\/artms-observer:/{p=1} p{print} p&&/^$/{exit}' "$BUILD/build.ninja")
[ -n "$line" ] || { echo "FAIL: no link rule for bin/artms-observer in $BUILD/build.ninja"; exit 1; }
for forbidden in libartms_truth_propagator sundials libartms_imaging; do
  if grep -q "$forbidden" <<<"$line"; then
    echo "FAIL: artms-observer links $forbidden"; exit 1
  fi
done
grep -q libartms_dynamics <<<"$line" || { echo "FAIL: check is blind (dynamics not seen on the link line)"; exit 1; }
echo "artms-observer links neither the truth propagator, SUNDIALS nor the renderer"
