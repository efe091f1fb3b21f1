#!/usr/bin/env python3
"""Independent reference for the dynamics (issue 3, acceptance point 2):
Starling SV4 (Table 2, PSE, 2024-05-08 00:00:00 UTC) propagated for one day
with poliastro's Cowell integrator (DOP853) and J2, same GM, radius and J2 as
the project's GGM01S-based "j2" force model.

The project's J2 acts about the ECEF z axis, which is the mean pole of date
(IAU 1976 precession); so the reference integrates in the mean-of-date frame
of the epoch (ERFA pmat76) and rotates the results back to J2000. The pole
moves by ~3e-7 rad during the day; its effect is far below the 1 m tolerance.

Writes OUT_DIR/sv4_j2_poliastro.json and OUT_DIR/erfa_earth_velocity_cases.json
(the Earth's barycentric velocity, ERFA epv00). Exit 77 when packages are missing.
"""
import json
import math
import sys

try:
    import numpy as np
    import erfa
    from poliastro.core.elements import coe2rv
    from poliastro.core.propagation import cowell, func_twobody
    from poliastro.core.perturbations import J2_perturbation
    from poliastro.core.angles import M_to_E, E_to_nu
    import poliastro
except ImportError as exc:  # pragma: no cover
    print(f"SKIP: oracle packages not importable with {sys.executable}: {exc}")
    sys.exit(77)

GM = 398600.4415          # km^3/s^2, GGM01S
R = 6378.1363             # km, GGM01S
J2 = 0.001082625521611732  # -sqrt(5) * C20bar (GGM01S coefficient line)

# TT Julian date of 2024-05-08T00:00:00 UTC (TT - UTC = 69.184 s).
JD_TT = 2460438.5 + 69.184 / 86400.0


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "."
    a, ex, ey = 6943.0, 0.0001, 0.0016
    i, raan, u = (math.radians(x) for x in (99.4, -38.0, -153.0))
    e = math.hypot(ex, ey)
    argp = math.atan2(ey, ex)
    M = u - argp
    M = (M + math.pi) % (2 * math.pi) - math.pi
    nu = float(E_to_nu(M_to_E(M, e), e))
    r0, v0 = coe2rv(GM, a * (1 - e * e), e, i, raan, argp, nu)
    P = erfa.pmat76(2451545.0, JD_TT - 2451545.0)  # J2000 -> mean of date
    r0m, v0m = P @ r0, P @ v0

    def f(t0, u_, k):
        du_kep = func_twobody(t0, u_, k)
        ax, ay, az = J2_perturbation(t0, u_, k, J2=J2, R=R)
        return du_kep + np.array([0, 0, 0, ax, ay, az])

    tofs = np.arange(0.0, 86400.0 + 1.0, 3600.0)
    rr, vv = cowell(GM, r0m, v0m, tofs, rtol=1e-13, f=f)
    cases = []
    for t, r, v in zip(tofs, rr, vv):
        cases.append({"t_s": float(t), "r_km": (P.T @ r).tolist(), "v_kms": (P.T @ v).tolist()})
    out = {"source": f"poliastro {poliastro.__version__} core.propagation.cowell (DOP853, rtol 1e-13) "
                     "with J2_perturbation about the mean pole of date (ERFA pmat76)",
           "epoch_utc": "2024-05-08T00:00:00Z",
           "initial_r_km": [float(x) for x in r0], "initial_v_kms": [float(x) for x in v0],
           "cases": cases}
    with open(f"{out_dir}/sv4_j2_poliastro.json", "w") as fh:
        json.dump(out, fh)
    print(f"wrote {len(cases)} SV4 J2 states to {out_dir}")
    # The Earth's barycentric velocity (ERFA epv00), 1990-2040, for
    # dynamics::earth_velocity_bcrs_mps (stellar aberration).
    rng = np.random.default_rng(20241205)
    ev = []
    for jd in rng.uniform(2447892.5, 2466154.5, 200):
        _, pvb = erfa.epv00(2451545.0, float(jd) - 2451545.0)
        ev.append({"tt_s_since_j2000": (float(jd) - 2451545.0) * 86400.0,
                   "v_mps": (pvb[1] * 149597870700.0 / 86400.0).tolist()})
    with open(f"{out_dir}/erfa_earth_velocity_cases.json", "w") as fh:
        json.dump({"source": f"pyerfa {erfa.__version__}: epv00 barycentric velocity of the Earth (BCRS)",
                   "cases": ev}, fh)
    print(f"wrote {len(ev)} Earth velocities to {out_dir}")


if __name__ == "__main__":
    main()
