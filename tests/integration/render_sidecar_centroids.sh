#!/usr/bin/env bash
# Renderer issue, acceptance 1: star images land where the truth sidecar says.
# Renders 5 noise-free frames (expected signal with bias, hot pixels and
# saturation, no faint stars) and, for every isolated catalog star, compares
# the background-subtracted intensity-weighted centroid (9x9 px window) with
# the position projected from the sidecar alone: RA/Dec -> unit vector ->
# q_cam_from_eci ([w, x, y, z], rotates ECI components into camera
# components) -> pinhole with fx, fy, cx, cy (and k1, k2).
#
# Tolerance: 0.02 px, or the 12-bit quantisation limit of the centroid when
# that is larger. The PNG holds integer DN, and rounding each pixel of a faint
# star moves a 9x9 centroid by up to ~16 DN px / F (F = star signal in DN,
# measured on these frames; rounding a pixel-integrated Gaussian model
# reproduces a faint star's window exactly, and the unrounded model's centroid
# is within 0.002 px), so the bound is max(0.02, 24 / F) px: 0.02 px for
# F >= 1200 DN (V < ~4.8), ~0.1 px for the faintest (V ~ 6.5-6.8,
# F ~ 200-270 DN). At least 10 stars must meet the plain 0.02 px bound. A
# rotation of q_cam_from_eci by 0.8 arcsec (0.023 px) fails the check.
set -euo pipefail
BIN=${ARTMS_BIN:?}; SRC=${ARTMS_SOURCE_DIR:?}; WORK=${1:?}
rm -rf "$WORK"; mkdir -p "$WORK"
"$BIN/artms-render" "$SRC/config/swarms/starling_pse.yaml" --observer SV4 --start 2024-05-08T00:30:00Z \
  --count 5 --every 600s --noise-free --out "$WORK/frames" 2> "$WORK/stderr" || { cat "$WORK/stderr"; exit 1; }
/usr/bin/python3 - "$WORK/frames" <<'PY'
import glob, json, math, os, sys
import numpy as np
from PIL import Image

frames = sys.argv[1]
HALF = 4              # centroid window (2 HALF + 1)^2 = 9x9 px, +-3.3 PSF sigma
ISO_PX = 12.0         # no other sidecar star or target closer than this
EDGE_PX = 8.0         # distance of the projected position from the sensor edge
TOL_PX = 0.02         # required agreement...
QUANT_DN_PX = 24.0    # ...or the quantisation limit QUANT_DN_PX / F if larger
SAT_DN = 4095         # 12-bit full scale: saturated stars are excluded (counted)


def r_cam_from_eci(q):
    """Rotation matrix of q_cam_from_eci = [w, x, y, z] (scalar first)."""
    w, x, y, z = (c / math.sqrt(sum(c * c for c in q)) for c in q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


checked, n_frames = [], 0
skipped = {"saturated": 0, "crowded": 0, "edge": 0, "hot pixel": 0}
sidecar_xy_diff = 0.0
for path in sorted(glob.glob(os.path.join(frames, "frame_*.json"))):
    side = json.load(open(path))
    assert not side["dropped"], f"{path}: dropped frame"
    assert side["exclusion"] == "none", f"{path}: excluded frame ({side['exclusion']})"
    img = np.asarray(Image.open(path[:-5] + ".png")).astype(np.float64)
    H, W = img.shape
    assert (W, H) == (side["width"], side["height"]), f"{path}: PNG size differs from the sidecar"
    n_frames += 1
    bg = float(np.median(img))  # bias + sky + dark: the level of empty pixels
    R = r_cam_from_eci(side["q_cam_from_eci"])
    fx, fy, cx, cy = side["fx_px"], side["fy_px"], side["cx_px"], side["cy_px"]
    k1, k2 = side["k1"], side["k2"]
    sources = [(s["x_px"], s["y_px"]) for s in side["stars"]]
    sources += [(t["x_px"], t["y_px"]) for t in side["targets"] if t["x_px"] is not None]
    for i, s in enumerate(side["stars"]):
        ra, dec = math.radians(s["ra_deg"]), math.radians(s["dec_deg"])
        X, Y, Z = R @ np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])
        assert Z > 0, f"{path}: star {s['catalog_id']} behind the camera"
        xn, yn = X / Z, Y / Z
        d = 1 + k1 * (xn * xn + yn * yn) + k2 * (xn * xn + yn * yn) ** 2
        px, py = cx + fx * xn * d, cy + fy * yn * d
        sidecar_xy_diff = max(sidecar_xy_diff, math.hypot(px - s["x_px"], py - s["y_px"]))
        if min(px + 0.5, py + 0.5, W - 0.5 - px, H - 0.5 - py) < EDGE_PX:
            skipped["edge"] += 1
            continue
        if any(j != i and math.hypot(ox - s["x_px"], oy - s["y_px"]) < ISO_PX
               for j, (ox, oy) in enumerate(sources)):
            skipped["crowded"] += 1
            continue
        ix, iy = int(round(px)), int(round(py))
        win = img[iy - HALF:iy + HALF + 1, ix - HALF:ix + HALF + 1]
        if win.max() >= SAT_DN:
            skipped["saturated"] += 1
            continue
        a = win - bg
        # Fixed hot pixels are not in the sidecar: a single-pixel spike far
        # above all four neighbours (a star's brightest pixel is at most ~1.4x
        # its brightest neighbour with the 1.2 px PSF).
        p = np.pad(a, 1)
        nb = np.maximum.reduce([p[:-2, 1:-1], p[2:, 1:-1], p[1:-1, :-2], p[1:-1, 2:]])
        if np.any((a > 20) & (a > 2 * nb + 10)):
            skipped["hot pixel"] += 1
            continue
        g = np.arange(-HALF, HALF + 1, dtype=np.float64)
        F = a.sum()
        mx = ix + (a.sum(axis=0) * g).sum() / F
        my = iy + (a.sum(axis=1) * g).sum() / F
        checked.append(dict(err=math.hypot(mx - px, my - py), tol=max(TOL_PX, QUANT_DN_PX / F), F=F,
                            hr=s["catalog_id"], vmag=s["vmag"], frame=os.path.basename(path)))

assert n_frames == 5, f"expected 5 frames, found {n_frames}"
print(f"render_sidecar_centroids: {n_frames} frames, {len(checked)} isolated stars checked; excluded: "
      + ", ".join(f"{v} {k}" for k, v in skipped.items()))
print(f"  sidecar x_px/y_px vs own projection: max {sidecar_xy_diff:.2e} px")
strict = [c for c in checked if c["tol"] == TOL_PX]
for name, group in (("all isolated", checked), (f"F >= {QUANT_DN_PX / TOL_PX:.0f} DN (tol {TOL_PX} px)", strict)):
    e = np.array([c["err"] for c in group])
    if len(e):
        print(f"  {name}: {len(e)} stars, centroid - projection: max {e.max():.4f} px, "
              f"rms {math.sqrt((e ** 2).mean()):.4f} px")
bad = [c for c in checked if c["err"] > c["tol"]]
for c in sorted(checked, key=lambda c: c["err"] / c["tol"], reverse=True)[:3]:
    print(f"  closest to its bound: HR {c['hr']} V {c['vmag']:.2f} F {c['F']:.0f} DN "
          f"err {c['err']:.4f} px (tol {c['tol']:.4f}) {c['frame']}")
assert not bad, f"{len(bad)} stars off their sidecar position: " + "; ".join(
    f"HR {c['hr']} in {c['frame']}: {c['err']:.4f} px > {c['tol']:.4f} px" for c in bad[:5])
assert len(checked) >= 20, f"only {len(checked)} isolated stars checked (need >= 20)"
assert len(strict) >= 10, f"only {len(strict)} stars bright enough for the {TOL_PX} px check (need >= 10)"
assert sidecar_xy_diff < 1e-6, f"sidecar x_px/y_px differ from the RA/Dec projection by {sidecar_xy_diff} px"
PY
