#!/usr/bin/env python3
"""The onboard model's expected error on a target's relative orbit from the
gravity it leaves out: the differential counterpart of gravity_budget.py.

A ground analysis that needs no truth run. The chief (--oe) and a target
(--roe-m, quasi-nonsingular a*ROE of D'Amico: a*[da, dlambda, dex, dey, dix,
diy], metres) are propagated with the full published field (artms-propagate,
GGM01S 120x120 by default, nothing else: drag, Sun and Moon are the onboard
model's too). Every --every minutes over --duration, both are propagated
from those states for a window of w minutes with the onboard field (10x10,
the paper's) and their osculating a*ROE compared with the full field's at
the window's end. For a random walk of spectral density Q the a*ROE error
covariance after w is Q w, so Q = <e e^T> / w (m^2/s, 6x6), per window.

Two spacecraft on one track a few seconds apart feel nearly the same high
degrees, so the error is small; but a close target whose relative orbit is
known to a few decimetres meets it in the covariance's thinnest directions
(docs/sod.md, "Unmodelled gravity in the thin directions").

The error of two spacecraft on one track is mostly short-periodic: after
30 to 90 minutes its RMS no longer grows (but for a*dlambda's secular part),
and half its covariance is then the covariance of the periodic term itself.

The target is placed at the chief's osculating elements plus the a*ROE, so
its initial osculating a*dlambda differs from the one asked by ~2 a de (the
mean and true anomalies); the budget does not depend on it.

Usage: relative_gravity_budget.py --oe a_m,e,i_deg,raan_deg,argp_deg,M_deg --roe-m=da,dl,dex,dey,dix,diy
       --epoch UTC [--full grav120] [--onboard grav10] [--windows 3,5,10,20] [--duration 1d]
       [--every 20] [--bin build/bin] [--json OUT]
Prints per window the diagonal of Q and its eigenvalues, then the periodic
term's 1-sigma per ROE (half the error's variance after the longest window,
a*dlambda 0), as the scenario key observers[].targets[]
{id: ..., gravity_periodic_roe_m: [...]} takes it (SCHEMA.md; SOD adds it to
the target's reported covariance); --json writes them with the matrices.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))
from gravity_budget import GM, states  # noqa: E402  (artms-propagate's CSV, the same GM)
ROE = ("da", "dlambda", "dex", "dey", "dix", "diy")


def qns_from_rv(x):
    """Osculating quasi-nonsingular elements (a, u, ex, ey, i, raan) of an ECI state (two-body)."""
    r, v = x[:3], x[3:]
    rn = np.linalg.norm(r)
    h = np.cross(r, v)
    i = math.acos(h[2] / np.linalg.norm(h))
    raan = math.atan2(h[0], -h[1])
    e_vec = np.cross(v, h) / GM - r / rn
    a = 1.0 / (2.0 / rn - v @ v / GM)
    n_hat = np.array([math.cos(raan), math.sin(raan), 0.0])
    w_hat = h / np.linalg.norm(h)
    m_hat = np.cross(w_hat, n_hat)
    ex, ey = e_vec @ n_hat, e_vec @ m_hat          # e cos(argp), e sin(argp)
    u = math.atan2(r @ m_hat, r @ n_hat)           # argument of latitude
    return np.array([a, u, ex, ey, i, raan])


def wrap(x):
    return (x + math.pi) % (2.0 * math.pi) - math.pi


def a_roe(chief, deputy):
    """D'Amico's quasi-nonsingular ROE of deputy w.r.t. chief (QNS elements), times the chief's a (m)."""
    a, u, ex, ey, i, raan = chief
    ad, ud, exd, eyd, id_, raand = deputy
    dr = wrap(raand - raan)
    return a * np.array([(ad - a) / a, wrap(ud - u) + dr * math.cos(i), exd - ex, eyd - ey, id_ - i,
                         dr * math.sin(i)])


def oe_of_deputy(oe, roe_m):
    """Keplerian elements (as artms-propagate --oe) of the deputy at the chief's oe plus a*ROE (m), with the
    chief's osculating elements taken as the QNS reference."""
    a, e, i, raan, argp, M = oe[0], oe[1], math.radians(oe[2]), math.radians(oe[3]), math.radians(oe[4]), \
        math.radians(oe[5])
    d = np.asarray(roe_m) / a
    ex, ey, u = e * math.cos(argp), e * math.sin(argp), argp + M  # M ~ the mean argument of latitude's part
    ad, exd, eyd, id_ = a * (1.0 + d[0]), ex + d[2], ey + d[3], i + d[4]
    draan = d[5] / math.sin(i)
    ud = u + d[1] - draan * math.cos(i)
    ed, argpd = math.hypot(exd, eyd), math.atan2(eyd, exd)
    return [ad, ed, math.degrees(id_), math.degrees(raan + draan), math.degrees(argpd),
            math.degrees(wrap(ud - argpd))]


def run(exe, start, duration, force, out, oe=None, rv=None):
    args = [exe, "--epoch", start, "--duration", duration, "--step", "60s", "--force", force, "--out", out]
    args += ["--oe", ",".join(f"{v:.12g}" for v in oe)] if oe is not None else \
        ["--rv", ",".join(f"{v:.6f}" for v in rv)]
    subprocess.run(args, check=True, capture_output=True)
    return states(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--oe", required=True, help="chief: a_m,e,i_deg,raan_deg,argp_deg,M_deg (as artms-propagate)")
    ap.add_argument("--roe-m", required=True, help="target: a*[da,dlambda,dex,dey,dix,diy] in m")
    ap.add_argument("--epoch", required=True, help="UTC, e.g. 2024-05-08T00:00:00Z")
    ap.add_argument("--full", default="grav120", help="the ground's best field (default grav120)")
    ap.add_argument("--onboard", default="grav10", help="the onboard field (default grav10, the paper's)")
    ap.add_argument("--windows", default="3,5,10,20", help="window lengths, minutes")
    ap.add_argument("--duration", default="1d")
    ap.add_argument("--every", type=int, default=20, help="minutes between window starts")
    ap.add_argument("--bin", default=os.path.join(os.path.dirname(__file__), "..", "..", "build", "bin"))
    ap.add_argument("--json", help="write the budget (matrices per window) to this file")
    a = ap.parse_args()
    exe = os.path.join(a.bin, "artms-propagate")
    if not os.access(exe, os.X_OK):
        sys.exit(f"relative_gravity_budget.py: error: {exe} not found (build first, or --bin)")
    try:
        oe = [float(v) for v in a.oe.split(",")]
        roe = [float(v) for v in a.roe_m.split(",")]
        windows = [int(w) for w in a.windows.split(",")]
    except ValueError as e:
        sys.exit(f"relative_gravity_budget.py: error: {e}")
    if len(oe) != 6 or len(roe) != 6 or not windows or min(windows) <= 0:
        sys.exit("relative_gravity_budget.py: error: --oe and --roe-m take 6 numbers, --windows positive minutes")
    result = {"oe": oe, "roe_m": roe, "epoch": a.epoch, "full": a.full, "onboard": a.onboard,
              "roe": list(ROE), "windows": []}
    with tempfile.TemporaryDirectory() as tmp:
        f_c, f_d, w_c, w_d = (os.path.join(tmp, n) for n in ("fc.csv", "fd.csv", "wc.csv", "wd.csv"))
        full_c = run(exe, a.epoch, a.duration, a.full, f_c, oe=oe)
        full_d = run(exe, a.epoch, a.duration, a.full, f_d, oe=oe_of_deputy(oe, roe))
        print(f"target at a*ROE {roe} m: initial osculating a*ROE "
              + " ".join(f"{x:.1f}" for x in a_roe(qns_from_rv(full_c[0][1]), qns_from_rv(full_d[0][1]))) + " m")
        print(f"{'window':>7} " + " ".join(f"{'q_' + n:>10}" for n in ROE) + "   eigenvalues (m^2/s)")
        for w in windows:
            errs = []
            for k in range(0, len(full_c) - w, a.every):
                t0 = full_c[k][0][:19] + "Z"
                c1 = run(exe, t0, f"{w}m", a.onboard, w_c, rv=full_c[k][1])[-1][1]
                d1 = run(exe, t0, f"{w}m", a.onboard, w_d, rv=full_d[k][1])[-1][1]
                onboard = a_roe(qns_from_rv(c1), qns_from_rv(d1))
                truth = a_roe(qns_from_rv(full_c[k + w][1]), qns_from_rv(full_d[k + w][1]))
                errs.append(onboard - truth)
            E = np.array(errs)
            Q = E.T @ E / len(E) / (60.0 * w)
            ev = np.linalg.eigvalsh(Q)
            print(f"{w:>5} m " + " ".join(f"{x:10.3g}" for x in np.diag(Q)) + "   " + " ".join(f"{x:.3g}" for x in ev))
            print(f"{'':>7} RMS error after the window (m): " + " ".join(f"{x:.3f}" for x in np.sqrt((E ** 2).mean(0))))
            result["windows"].append({"minutes": w, "samples": len(E), "q_m2ps": Q.tolist(),
                                      "rms_error_m": np.sqrt((E ** 2).mean(axis=0)).tolist()})
    # The periodic term's own 1-sigma: half the error's variance at the longest window (a*dlambda's part
    # is secular and the bearings follow it: 0), as the scenario key observers[].targets[]
    # {id, gravity_periodic_roe_m} wants it.
    last = result["windows"][-1]
    var = np.diag(np.array(last["q_m2ps"])) * 60.0 * last["minutes"] * 0.5
    var[1] = 0.0
    result["gravity_periodic_roe_m"] = [float(x) for x in np.sqrt(var)]
    print(f"gravity_periodic_roe_m: [{', '.join(f'{x:.3f}' for x in result['gravity_periodic_roe_m'])}]"
          f"   (half the variance after {last['minutes']} min; a*dlambda 0)")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(result, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
