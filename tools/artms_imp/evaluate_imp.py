#!/usr/bin/env python3
"""Compares artms-imp outputs with artms-render truth sidecars.

usage: evaluate_imp.py FRAMES_DIR IMP_OUT_DIR [--json FILE]
Prints attitude success rate on frames with >= 4 catalog stars of V <= 6.5,
the rate of accepted attitudes wrong by more than 1 arcmin, the attitude error
(cross-boresight and roll, 1-sigma and max), and the bearing error of target
detections (the measurement candidate nearest to each visible target's true
pixel, within 3 px), and SAMUS tracking: assignment precision (tracked
measurements whose truth target is their track's), recall (target detections
that ended in a track) and identity across eclipses (consecutive visibility
segments of a target, split by gaps longer than 15 minutes, carried by the same
track id). Uses only Debian's numpy.
"""
import glob, json, math, os, sys
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "python"))
from artms_tools.codes import FrameStatus, is_samus_track  # noqa: E402
from artms_tools.runfolder import read_csv  # noqa: E402


def rot(q):  # [w, x, y, z], scalar first, rotates ECI components into camera components
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def main():
    frames_dir, out_dir = sys.argv[1], sys.argv[2]
    att = {r.int("frame"): r for r in read_csv(os.path.join(out_dir, "attitude.csv"), required=("frame", "status"))}
    meas = {}
    for r in read_csv(os.path.join(out_dir, "measurements.csv"), required=("frame", "track_id", "x_px", "y_px")):
        meas.setdefault(r.int("frame"), []).append(r)
    eligible = solved = wrong = 0
    labelled = []  # (t_ns, truth target, track id) of candidates matching a target
    cross, roll, bearing = [], [], []
    cross_z2 = []  # per-axis squared cross-boresight error / claimed attitude 1-sigma
    tracked_rows = []  # (track id, truth target or None)
    for side in sorted(glob.glob(os.path.join(frames_dir, "frame_*.json"))):
        k = int(os.path.basename(side)[6:12])
        j = json.load(open(side))
        if j.get("dropped"):
            continue
        for m in meas.get(k, []):
            label = None
            for t in j["targets"]:
                if t["x_px"] is not None and \
                        math.hypot(float(m["x_px"]) - t["x_px"], float(m["y_px"]) - t["y_px"]) < 3:
                    label = t["id"]
            if label is not None:
                labelled.append((int(m["t_tt_ns"]), label, int(m["track_id"])))
            if is_samus_track(m["track_id"]):
                tracked_rows.append((int(m["track_id"]), label))
        bright = [s for s in j["stars"] if s["vmag"] <= 6.5]
        if len(bright) < 4:
            continue
        eligible += 1
        a = att.get(k)
        if not a or FrameStatus.parse(a["status"]) != FrameStatus.OK:
            continue
        solved += 1
        Rt = rot(j["q_cam_from_eci"])
        Re = rot([float(a[c]) for c in ("qw", "qx", "qy", "qz")])
        D = Re @ Rt.T  # error rotation in camera axes
        ang = math.acos(max(-1.0, min(1.0, (np.trace(D) - 1) / 2)))
        if ang > math.radians(1 / 60):
            wrong += 1
            continue
        # Small-angle error vector (camera axes): x, y cross-boresight, z roll.
        e = np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]]) / 2
        cross.append(math.hypot(e[0], e[1]))
        sig = a.get("attitude_sigma_arcsec")
        if sig:
            s_rad = float(sig) * math.pi / (180 * 3600)
            cross_z2.append((e[0] ** 2 + e[1] ** 2) / (2 * s_rad ** 2))
        roll.append(abs(e[2]))
        for t in j["targets"]:
            if not t["visible"] or t["x_px"] is None:
                continue
            best = None
            for m in meas.get(k, []):
                d = math.hypot(float(m["x_px"]) - t["x_px"], float(m["y_px"]) - t["y_px"])
                if d < 3 and (best is None or d < best[0]):
                    best = (d, m)
            if best:
                fx, cx, cy = j["fx_px"], j["cx_px"], j["cy_px"]
                v = np.array([(t["x_px"] - cx) / fx, (t["y_px"] - cy) / j["fy_px"], 1.0])
                u_true = Rt.T @ (v / np.linalg.norm(v))
                m = best[1]
                u = np.array([float(m["ux_eci"]), float(m["uy_eci"]), float(m["uz_eci"])])
                bearing.append(math.acos(max(-1.0, min(1.0, float(u @ u_true)))))
    # Tracking: a track's target is the truth target of most of its measurements.
    from collections import Counter
    votes = {}
    for tid, label in tracked_rows:
        votes.setdefault(tid, Counter())[label] += 1
    track_target = {tid: c.most_common(1)[0][0] for tid, c in votes.items()}
    correct = sum(1 for tid, label in tracked_rows if label is not None and label == track_target[tid])
    recall_hits = sum(1 for _, _, tid in labelled if is_samus_track(tid))
    # Identity across eclipses: per target, segments of detections split by gaps > 15 min.
    joins = kept = 0
    by_target = {}
    for t_ns, label, tid in sorted(labelled):
        by_target.setdefault(label, []).append((t_ns, tid))
    for label, rows in by_target.items():
        segs, cur = [], [rows[0]]
        for a, b in zip(rows, rows[1:]):
            if b[0] - a[0] > 15 * 60 * 10**9:
                segs.append(cur)
                cur = []
            cur.append(b)
        segs.append(cur)
        ids = [Counter(tid for _, tid in sg if is_samus_track(tid)).most_common(1) for sg in segs]
        for a, b in zip(ids, ids[1:]):
            if not a or not b:
                continue  # a segment that was never tracked (counted in recall)
            joins += 1
            kept += a[0][0] == b[0][0]
    arc = 180 / math.pi * 3600
    res = {
        "frames_with_4_stars": eligible, "attitude_solved": solved,
        "solved_fraction": solved / eligible if eligible else None,
        "accepted_wrong_gt_1arcmin": wrong,
        "wrong_fraction": wrong / solved if solved else None,
        "cross_boresight_1sigma_arcsec": float(np.sqrt(np.mean(np.square(cross))) * arc) if cross else None,
        "cross_boresight_max_arcsec": float(max(cross) * arc) if cross else None,
        # 1 when attitude_sigma_arcsec (per axis) matches the errors.
        "cross_boresight_error_over_sigma_rms": float(np.sqrt(np.mean(cross_z2))) if cross_z2 else None,
        "roll_1sigma_arcsec": float(np.sqrt(np.mean(np.square(roll))) * arc) if roll else None,
        "target_detections_matched": len(bearing),
        "target_bearing_1sigma_arcsec": float(np.sqrt(np.mean(np.square(bearing))) * arc) if bearing else None,
        "target_bearing_max_arcsec": float(max(bearing) * arc) if bearing else None,
        "tracked_measurements": len(tracked_rows), "tracks": len(votes),
        "track_targets": {str(k): v for k, v in sorted(track_target.items())},
        "assignment_precision": correct / len(tracked_rows) if tracked_rows else None,
        "target_detections": len(labelled), "target_detections_tracked": recall_hits,
        "recall": recall_hits / len(labelled) if labelled else None,
        "eclipse_gaps": joins, "eclipse_gaps_same_identity": kept,
        "identity_fraction": kept / joins if joins else None,
    }
    print(json.dumps(res, indent=1))
    if "--json" in sys.argv:
        json.dump(res, open(sys.argv[sys.argv.index("--json") + 1], "w"), indent=1)


if __name__ == "__main__":
    main()
