#!/usr/bin/env python3
"""The onboard model's expected error on an observer's own orbit from the
gravity it leaves out, as SOD's `observer_acceleration_sigma_mps2` budget.

A ground analysis that needs no truth run: from states of the full published
field (artms-propagate, GGM01S 120x120 by default) every --every minutes over
--duration, the onboard model (gravity 10x10 by default, the paper's) is
propagated for a window of dt minutes and compared with the full field. For a
velocity random walk of spectral density q_v the position variance over dt is
q_v dt^3 / 3, so q_v = 3 <dr^2> / dt^3 per RTN axis; SOD's budget is an
acceleration correlated over one orbit, q_v = 2 sigma^2 T
(sod::observer_process_noise_from_acceleration), so sigma = sqrt(q_v / (2 T)).

Usage: gravity_budget.py --oe a_m,e,i_deg,raan_deg,argp_deg,M_deg --epoch UTC
       [--full grav120,drag,sun,moon] [--onboard grav10,drag,sun,moon]
       [--windows 3,5,10,20] [--duration 1d] [--every 20] [--bin build/bin]
Prints sigma per RTN axis for each window and their RMS over axes and windows.
"""
import argparse
import csv
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

GM = 3.986004415e14


def states(path):
    out = []
    for r in csv.DictReader(open(path)):
        out.append((r["t_utc"], np.array([float(r[k]) for k in ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")])))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--oe", required=True, help="a_m,e,i_deg,raan_deg,argp_deg,M_deg (as artms-propagate)")
    ap.add_argument("--epoch", required=True, help="UTC, e.g. 2024-05-08T00:00:00Z")
    ap.add_argument("--full", default="grav120,drag,sun,moon", help="the ground's best model")
    ap.add_argument("--onboard", default="grav10,drag,sun,moon", help="the onboard model")
    ap.add_argument("--windows", default="3,5,10,20", help="window lengths, minutes")
    ap.add_argument("--duration", default="1d")
    ap.add_argument("--every", type=int, default=20, help="minutes between window starts")
    ap.add_argument("--bin", default=os.path.join(os.path.dirname(__file__), "..", "..", "build", "bin"))
    a = ap.parse_args()
    exe = os.path.join(a.bin, "artms-propagate")
    if not os.access(exe, os.X_OK):
        sys.exit(f"gravity_budget.py: error: {exe} not found (build first, or --bin)")
    a_m = float(a.oe.split(",")[0])
    period_s = 2.0 * math.pi * math.sqrt(a_m**3 / GM)
    windows = [int(w) for w in a.windows.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        full_csv, win_csv = os.path.join(tmp, "full.csv"), os.path.join(tmp, "win.csv")
        subprocess.run([exe, "--epoch", a.epoch, "--oe", a.oe, "--duration", a.duration, "--step", "60s",
                        "--force", a.full, "--out", full_csv], check=True, capture_output=True)
        full = states(full_csv)
        sigmas = []
        for w in windows:
            d = []
            for k in range(0, len(full) - w, a.every):
                t0, x0 = full[k]
                subprocess.run([exe, "--epoch", t0[:19] + "Z", "--rv", ",".join(f"{v:.6f}" for v in x0),
                                "--duration", f"{w}m", "--step", "60s", "--force", a.onboard, "--out", win_csv],
                               check=True, capture_output=True)
                x1 = states(win_csv)[-1][1]
                xf = full[k + w][1]
                r, v = xf[:3], xf[3:]
                R = r / np.linalg.norm(r)
                N = np.cross(r, v)
                N /= np.linalg.norm(N)
                T = np.cross(N, R)
                e = x1[:3] - xf[:3]
                d.append([e @ R, e @ T, e @ N])
            d = np.array(d)
            ms = (d**2).mean(axis=0)
            q_v = 3.0 * ms / (60.0 * w) ** 3
            s = np.sqrt(q_v / (2.0 * period_s))
            sigmas.append(s)
            print(f"window {w:2d} min ({len(d)} windows): RMS error R/T/N {np.sqrt(ms).round(3)} m; "
                  f"sigma R/T/N {s[0]:.2e} {s[1]:.2e} {s[2]:.2e} m/s^2")
        rms = float(np.sqrt(np.mean(np.square(sigmas))))
        print(f"observer_acceleration_sigma_mps2 (RMS over axes and windows): {rms:.2e} m/s^2 "
              f"({a.onboard} against {a.full}, orbit period {period_s:.0f} s)")


if __name__ == "__main__":
    main()
