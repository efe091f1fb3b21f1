#!/usr/bin/env python3
"""Independent references for common/astro, computed with Debian's poliastro
(Keplerian -> Cartesian) and pyerfa (IAU 1976 precession, IAU 1982 GMST,
stellar aberration).

Writes OUT_DIR/kepler_poliastro_cases.json, OUT_DIR/erfa_earth_rotation_cases.json
and OUT_DIR/erfa_aberration_cases.json.
Exit code 77 (ctest SKIP_RETURN_CODE) when the oracle packages are missing.
"""
import json
import math
import sys

try:
    import numpy as np
    import erfa
    from poliastro.core.elements import coe2rv
    import poliastro
except ImportError as exc:  # pragma: no cover - depends on the machine
    print(f"SKIP: oracle packages not importable with {sys.executable}: {exc}")
    sys.exit(77)

GM_KM3S2 = 398600.4415  # GGM01S, the same GM the C++ side uses
R_EARTH_KM = 6378.1363


def kepler_cases(rng, count):
    cases = []
    for k in range(count):
        a_km = math.exp(rng.uniform(math.log(6678.0), math.log(42164.0)))
        e_max = min(0.7, 1.0 - (R_EARTH_KM + 100.0) / a_km)
        e = rng.uniform(0.0, max(e_max, 0.0))
        i = rng.uniform(0.0, math.pi)
        raan, argp, nu = (rng.uniform(0.0, 2 * math.pi) for _ in range(3))
        # Singular geometries the C++ side must handle without blowing up.
        if k % 10 == 0:
            e = 0.0
        if k % 10 == 1:
            i = 0.0
        if k % 10 == 2:
            e, i = 0.0, 0.0
        if k % 10 == 3:
            i = math.pi
        if k % 10 == 4:
            i = math.pi / 2
        p = a_km * (1.0 - e * e)
        r, v = coe2rv(GM_KM3S2, p, e, i, raan, argp, nu)
        cases.append({"a_km": a_km, "e": e, "i_rad": i, "raan_rad": raan,
                      "argp_rad": argp, "nu_rad": nu,
                      "r_km": [float(x) for x in r], "v_kms": [float(x) for x in v]})
    return cases


def erfa_cases(rng, count):
    cases = []
    for _ in range(count):
        # JD TT between 1990 and 2040; UT1 taken equal to UTC, i.e. TT - 32.184 - dAT.
        jd_tt = rng.uniform(2447892.5, 2466154.5)
        cases.append({
            "jd_tt": jd_tt,
            "pmat76": erfa.pmat76(2451545.0, jd_tt - 2451545.0).tolist(),
        })
    return cases


def aberration_cases(rng, count):
    """erfa.ab: a unit direction seen from an observer moving at v (units of c),
    1 au from the Sun. Speeds up to 60 km/s (an observer in LEO about the Sun:
    about 38 km/s)."""
    c = 299792458.0
    cases = []
    for _ in range(count):
        u = np.array([rng.uniform(-1, 1) for _ in range(3)])
        u /= np.linalg.norm(u)
        v = np.array([rng.uniform(-1, 1) for _ in range(3)])
        v *= rng.uniform(0.0, 60000.0) / np.linalg.norm(v)
        b = v / c
        ppr = erfa.ab(u, b, 1.0, math.sqrt(1.0 - b @ b))
        cases.append({"u": u.tolist(), "v_mps": v.tolist(), "apparent": (ppr / np.linalg.norm(ppr)).tolist()})
    return cases


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else "."
    rng = np.random.default_rng(20240508)

    class R:  # thin adapter: rng.uniform(lo, hi) -> float
        def uniform(self, lo, hi):
            return float(rng.uniform(lo, hi))

    r = R()
    kep = {"source": f"poliastro {poliastro.__version__} core.elements.coe2rv, GM {GM_KM3S2} km^3/s^2",
           "cases": kepler_cases(r, 1000)}
    with open(f"{out_dir}/kepler_poliastro_cases.json", "w") as f:
        json.dump(kep, f)
    ero = {"source": f"pyerfa {erfa.__version__}: pmat76 (IAU 1976 precession J2000 -> mean of date)",
           "cases": erfa_cases(r, 200)}
    # GMST 1982 against UT1 dates given as calendar UTC strings (UT1 = UTC).
    gm = []
    for _ in range(200):
        jd_utc = r.uniform(2447892.5, 2466154.5)
        day = math.floor(jd_utc - 0.5) + 0.5
        frac = jd_utc - day
        iy, im, idd, fd = erfa.jd2cal(day, frac)
        hh = fd * 24.0
        h = int(hh)
        mm = (hh - h) * 60.0
        mi = int(mm)
        ss = round((mm - mi) * 60.0, 3)
        if ss >= 60.0:
            continue
        utc = f"{int(iy):04d}-{int(im):02d}-{int(idd):02d}T{h:02d}:{mi:02d}:{ss:06.3f}Z"
        d1, d2 = erfa.dtf2d("UTC", int(iy), int(im), int(idd), h, mi, ss)
        gm.append({"utc": utc, "gmst82_rad": float(erfa.gmst82(d1, d2))})
    ero["gmst_cases"] = gm
    with open(f"{out_dir}/erfa_earth_rotation_cases.json", "w") as f:
        json.dump(ero, f)
    ab = {"source": f"pyerfa {erfa.__version__}: ab (stellar aberration, observer 1 au from the Sun)",
          "cases": aberration_cases(r, 500)}
    with open(f"{out_dir}/erfa_aberration_cases.json", "w") as f:
        json.dump(ab, f)
    print(f"wrote {len(kep['cases'])} Kepler cases and {len(ero['cases'])}+{len(gm)} ERFA cases to {out_dir}")


if __name__ == "__main__":
    main()
