#!/usr/bin/python3
"""Monte Carlo of one scenario over seeds: NEES consistency of SOD.

usage: monte_carlo.py SCENARIO.yaml --runs 20 --orbits 12 --out DIR [--bin build/bin] [--first-seed 1]

Runs `artms-swarm run SCENARIO --seed s --orbits N --out DIR/seed_<s>` for each
seed (a run already present with a summary.json is reused), then per observer
and target: the NEES of the six ROE averaged over the runs at every navigation
step, the two-sided 95 % band of that average (chi-square with 6 R degrees of
freedom divided by R, R = runs), and the fraction of steps after convergence
inside the band. "After convergence": from the latest convergence_orbits of
the runs (summary.json), or the second half of the run when a run never
converged; the same fraction after the median convergence is reported too
(a single slow run moves the latest one to the end of the run). Writes
DIR/mc_summary.json and DIR/mc_nees_<observer>_<target>.png.
Needs Debian's python3-numpy, python3-scipy, python3-matplotlib.
"""
import argparse, csv, json, os, subprocess, sys
import numpy as np
from scipy.stats import chi2
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--orbits", type=float, default=12)
    ap.add_argument("--out", required=True)
    ap.add_argument("--bin", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "build", "bin"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    seeds = list(range(a.first_seed, a.first_seed + a.runs))
    for i, s in enumerate(seeds):
        d = os.path.join(a.out, f"seed_{s}")
        if os.path.exists(os.path.join(d, "summary.json")):
            continue
        print(f"monte carlo: run {i + 1}/{len(seeds)} (seed {s})", file=sys.stderr, flush=True)
        r = subprocess.run([os.path.join(a.bin, "artms-swarm"), "run", a.scenario, "--seed", str(s), "--orbits",
                            str(a.orbits), "--out", d], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if r.returncode != 0:
            print(f"monte carlo: seed {s} failed:\n{r.stderr[-2000:]}", file=sys.stderr)
            return 1
    nees = {}      # (obs, tgt) -> list over runs of {t: nees}
    conv = {}      # (obs, tgt) -> list of convergence orbits (None if never)
    period = None
    for s in seeds:
        d = os.path.join(a.out, f"seed_{s}")
        summ = json.load(open(os.path.join(d, "summary.json")))
        for obs, o in summ["observers"].items():
            period = o.get("period_s", period)
            for tgt, t in o.get("targets", {}).items():
                conv.setdefault((obs, tgt), []).append(t.get("convergence_orbits"))
        per = {}
        for r in csv.DictReader(open(os.path.join(d, "eval", "targets.csv"))):
            per.setdefault((r["observer"], r["target"]), {})[int(r["t_tt_ns"])] = float(r["nees"])
        for k, v in per.items():
            nees.setdefault(k, []).append(v)
    R = len(seeds)
    lo, hi = chi2.ppf(0.025, 6 * R) / R, chi2.ppf(0.975, 6 * R) / R
    out = {"scenario": a.scenario, "runs": R, "seeds": seeds, "band_95": [lo, hi], "targets": {}}
    for (obs, tgt), runs in sorted(nees.items()):
        times = sorted(set.intersection(*[set(r) for r in runs]))
        M = np.array([[r[t] for t in times] for r in runs])
        ok_cols = np.all(np.isfinite(M), axis=0)
        t0 = times[0]
        orb = (np.array(times) - t0) * 1e-9 / (period or 5700.0)
        cs = conv[(obs, tgt)]
        start = max(cs) if cs and all(c is not None for c in cs) else orb[-1] / 2
        sel = (orb >= start) & ok_cols
        avg = np.nanmean(M, axis=0)
        inside = (avg >= lo) & (avg <= hi)
        frac = float(np.mean(inside[sel])) if sel.any() else None
        done = [c for c in cs if c is not None]
        start_med = float(np.median(done)) if done else orb[-1] / 2
        sel_med = (orb >= start_med) & ok_cols
        frac_med = float(np.mean(inside[sel_med])) if sel_med.any() else None
        out["targets"][f"{obs}/{tgt}"] = {
            "after_orbit": float(start), "steps": int(sel.sum()), "frac_inside_band": frac,
            "mean_nees_after": float(np.mean(avg[sel])) if sel.any() else None,
            "after_median_orbit": start_med, "steps_after_median": int(sel_med.sum()),
            "frac_inside_band_after_median": frac_med,
            "convergence_orbits": cs}
        plt.figure(figsize=(8, 3.5))
        plt.semilogy(orb, avg, "k-", lw=0.8, label=f"average NEES over {R} runs")
        plt.axhspan(lo, hi, color="tab:green", alpha=0.25, label=f"95 % band [{lo:.2f}, {hi:.2f}]")
        plt.axhline(6, color="tab:green", lw=0.8)
        plt.axvline(start, color="tab:red", ls="--", lw=0.8, label="latest convergence")
        plt.axvline(start_med, color="tab:orange", ls=":", lw=0.8, label="median convergence")
        plt.xlabel("orbits"); plt.ylabel("NEES (6 ROE)")
        title = f"{obs} -> {tgt}"
        if frac is not None:
            title += f": {100 * frac:.1f} % of steps inside the band after the latest convergence"
        if frac_med is not None:
            title += f", {100 * frac_med:.1f} % after the median"
        plt.title(title, fontsize=9)
        plt.legend(fontsize=8, loc="upper right"); plt.grid(alpha=0.3); plt.tight_layout()
        plt.savefig(os.path.join(a.out, f"mc_nees_{obs}_{tgt}.png"), dpi=120)
        plt.close()
    json.dump(out, open(os.path.join(a.out, "mc_summary.json"), "w"), indent=1)
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
