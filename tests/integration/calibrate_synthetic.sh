#!/usr/bin/env bash
# artms-calibrate recovers a known distortion (issue 19): 30 frames of SV4
# rendered by artms-render with a camera whose lens has barrel distortion
# k1 = -0.1 and tangential (decentring) distortion p1 = 2e-3, p2 = -1.5e-3
# (~0.7 px at the corners), solved by artms-imp with the same camera file
# but p1 = p2 = 0, then fitted with --fit-tangential: p1 and p2 within
# 3e-4 of the truth, k1 within 0.02, f within 0.02 %, and the pixel residual
# smaller than before the fit.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
CAM="$SRC/config/cameras/nst_ideal.yaml"
sed 's/^  k1: 0.0 .*/  k1: -0.1/; s/^  p1: 0.0 .*/  p1: 0.002/; s/^  p2: 0.0$/  p2: -0.0015/' "$CAM" > "$WORK/lens.yaml"
sed 's/^  p1: 0.002/  p1: 0.0/; s/^  p2: -0.0015/  p2: 0.0/' "$WORK/lens.yaml" > "$WORK/no_tangential.yaml"
grep -q "p1: 0.002" "$WORK/lens.yaml" && grep -q "p2: -0.0015" "$WORK/lens.yaml" && grep -q "k1: -0.1" "$WORK/lens.yaml"
grep -q "p1: 0.0$" "$WORK/no_tangential.yaml"
"$BIN/artms-render" "$SRC/config/swarms/starling_pse.yaml" --observer SV4 --count 30 --every 60s \
  --camera "$WORK/lens.yaml" --out "$WORK/frames" 2> "$WORK/render.err"
"$BIN/artms-imp" "$WORK/no_tangential.yaml" "$WORK/frames" --out "$WORK/imp" 2> "$WORK/imp.err"
"$BIN/artms-calibrate" "$WORK/no_tangential.yaml" "$WORK/imp" --time 2024-05-08T00:00:00Z --fit-tangential \
  --out "$WORK/fit.yaml" > "$WORK/calibrate.out"
cat "$WORK/calibrate.out"
/usr/bin/python3 - "$WORK" <<'PY'
import re, sys
work = sys.argv[1]
out = open(f"{work}/calibrate.out").read()
fit = {m.group(1): float(m.group(2)) for m in re.finditer(r"^\s+(\w+)\s+(\S+) \+- ", out, re.M)}
after, before = map(float, re.search(r"RMS ([0-9.]+) px \(before ([0-9.]+) px\)", out).groups())
f0 = 30e-3 / 5.3e-6
print(f"fitted: f {fit['f_px']:.2f} px ({100 * (fit['f_px'] / f0 - 1):+.4f} %), k1 {fit['k1']:.4f}, "
      f"p1 {fit['p1']:.2e}, p2 {fit['p2']:.2e}; residual {before:.3f} -> {after:.3f} px")
assert abs(fit["p1"] - 2e-3) < 3e-4, fit
assert abs(fit["p2"] + 1.5e-3) < 3e-4, fit
assert abs(fit["k1"] + 0.1) < 0.02, fit
assert abs(fit["f_px"] / f0 - 1) < 2e-4, fit
assert after < before, (before, after)
text = open(f"{work}/fit.yaml").read()
assert re.search(r"^  p1: ", text, re.M) and re.search(r"^  p2: ", text, re.M), text
print("calibrate_synthetic: ok")
PY
