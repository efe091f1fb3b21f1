#!/usr/bin/python3
"""Replay a campaign: artms-sod-replay on every seed of a campaign folder, with other filter options, and the
campaign's NEES band statistics of the replays.

usage: replay_campaign.py CAMPAIGN_DIR --out DIR [--jobs 2] [--bin build/bin] [--after-orbit X]
                          [-- REPLAY OPTIONS...]

A tuning study without running the swarm again: each seed s of CAMPAIGN_DIR (campaign.py's folder; its
campaign_summary.json lists the seeds) is `artms-sod-replay CAMPAIGN_DIR/seed_<s> --csv DIR/seed_<s>.csv
REPLAY OPTIONS` (e.g. `-- --adaptive-process-noise false`, `-- --drag-density-error 0.3`; see tools/README.md,
artms-sod-replay). The replay fuses the recorded bearings, joined to the truth by frame, and has no BOD,
health checks or filter lag, so it is compared with the replay of the same campaign without options, not with
the live figures: run it once with no options as the baseline.

Per target, over the steps at or after --after-orbit (default: the campaign's own after_orbit for that target,
the latest convergence or the run's second half): the 20-run average NEES against the two-sided 95 % band
chi2(6R)/R, the fractions of steps inside, above and below it, the mean NEES, the mean (error/1-sigma)^2 per ROE
and the largest share of any seed's steps with its NEES beyond the 3-sigma and 5-sigma quantiles of chi2(6).
Writes DIR/replay_summary.json and prints a table. Progress on stderr; a seed whose replay fails is recorded
(exit code, last lines of its output) and the others go on. Exit 0 when every seed was replayed, 1 when one
failed, 2 on a usage error. Needs Debian's python3-numpy and python3-scipy.
"""
import argparse
import concurrent.futures
import csv
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "python"))
sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))
from artms_tools.runfolder import ROE_NAMES as ROE, RunFolderError, principal_z2, read_summary  # noqa: E402
from campaign import nees_spread_entry, run_epoch_tt_ns  # noqa: E402

TAIL_LINES = 20


def say(msg):
    print(f"replay_campaign: {msg}", file=sys.stderr, flush=True)


def parse_args(argv):
    extra = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1:]
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("campaign", help="a campaign.py output folder")
    ap.add_argument("--out", required=True, help="output folder (replay CSVs, replay_summary.json)")
    ap.add_argument("--jobs", type=int, default=2, help="seeds replayed at a time (default 2)")
    ap.add_argument("--bin", default=os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..",
                                                  "build", "bin"), help="folder of artms-sod-replay")
    ap.add_argument("--after-orbit", type=float, help="statistics from this orbit on (default: the campaign's)")
    a = ap.parse_args(argv)
    a.replay_options = extra
    if a.jobs < 1:
        ap.error("--jobs must be at least 1")
    return a


def replay(exe, seed_dir, out_csv, options):
    p = subprocess.run([exe, seed_dir, "--csv", out_csv] + options, capture_output=True, text=True)
    tail = "\n".join((p.stdout + p.stderr).strip().splitlines()[-TAIL_LINES:])
    return p.returncode, tail


def read_replay(path):
    """{target: {t_tt_ns: row}} of one replay CSV."""
    out = {}
    with open(path) as f:
        for r in csv.DictReader(f):
            out.setdefault(r["target"], {})[int(r["t_tt_ns"])] = r
    return out


def target_stats(per_seed, after_orbit, period_s):
    """Band statistics of one target over the seeds' replays ({seed: {t: row}}, times since each run's start)."""
    import numpy as np
    from scipy.stats import chi2
    times = sorted(set.intersection(*[set(v) for v in per_seed.values()]))
    if not times:
        return None
    t0 = times[0]  # as campaign.py: orbits since the first step all runs share
    times = [t for t in times if (t - t0) * 1e-9 / period_s >= after_orbit]
    if not times:
        return None
    seeds = sorted(per_seed)
    nees = np.array([[float(per_seed[s][t]["nees"] or "nan") for t in times] for s in seeds])
    R = len(seeds)
    lo, hi = chi2.ppf(0.025, 6 * R) / R, chi2.ppf(0.975, 6 * R) / R
    with np.errstate(invalid="ignore"):
        avg = np.nanmean(nees, axis=0)
    z2 = []
    for n in ROE:
        z = [[float(per_seed[s][t][f"err_a_{n}_m"]) / float(per_seed[s][t][f"sigma_a_{n}_m"]) for t in times]
             for s in seeds]
        z2.append(float(np.nanmean(np.square(z))))
    q3, q5 = chi2.ppf(0.9973, 6), chi2.ppf(1.0 - 5.733e-7, 6)
    # (error / 1-sigma)^2 along the reported covariance's principal directions, thinnest first (campaign.py's
    # by_direction): 1 each when consistent; the six sum to the NEES.
    by_direction = None
    if "cov_upper_m2" in per_seed[seeds[0]][times[0]]:
        zs = [principal_z2(r["cov_upper_m2"].split(), [float(r[f"err_a_{n}_m"]) for n in ROE])
              for r in (per_seed[s][t] for s in seeds for t in times)]
        zs = [z for z in zs if z is not None]
        by_direction = [float(x) for x in np.mean(zs, axis=0)] if zs else None
    return {"runs": R, "band_95": [float(lo), float(hi)], "after_orbit": after_orbit, "steps": len(times),
            "frac_inside_band": float(np.mean((avg >= lo) & (avg <= hi))),
            "frac_above_band": float(np.mean(avg > hi)), "frac_below_band": float(np.mean(avg < lo)),
            "mean_nees": float(np.nanmean(avg)), "roe": list(ROE), "mean_z2_per_roe": z2,
            "worst_seed_frac_beyond_3sigma": float(np.max(np.nanmean(nees > q3, axis=1))),
            "worst_seed_frac_beyond_5sigma": float(np.max(np.nanmean(nees > q5, axis=1))),
            "mean_z2_per_principal_direction": by_direction, "nees_spread": nees_spread_entry(nees)}


def main(argv=None):
    a = parse_args(sys.argv[1:] if argv is None else argv)
    exe = os.path.join(a.bin, "artms-sod-replay")
    if not os.access(exe, os.X_OK):
        print(f"replay_campaign.py: error: {exe} not found (build first, or --bin)", file=sys.stderr)
        return 2
    cs_path = os.path.join(a.campaign, "campaign_summary.json")
    try:
        with open(cs_path) as f:
            cs = json.load(f)
        seeds = [int(s) for s in cs["seeds"]]
    except (OSError, ValueError, KeyError, TypeError) as e:
        print(f"replay_campaign.py: error: {cs_path}: {e} (not a campaign.py folder?)", file=sys.stderr)
        return 2
    os.makedirs(a.out, exist_ok=True)
    jobs = [(s, os.path.join(a.campaign, f"seed_{s}"), os.path.join(a.out, f"seed_{s}.csv")) for s in seeds]
    say(f"{len(jobs)} seeds of {a.campaign}, {a.jobs} at a time, replay options: "
        + (" ".join(a.replay_options) or "(none)"))
    failures, done = [], []
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as ex:
        futures = {ex.submit(replay, exe, d, out, a.replay_options): s for s, d, out in jobs}
        for fut in concurrent.futures.as_completed(futures):
            s = futures[fut]
            rc, tail = fut.result()
            if rc == 0:
                done.append(s)
                say(f"seed {s} replayed [{len(done) + len(failures)}/{len(jobs)}]")
            else:
                failures.append({"seed": s, "exit_code": rc, "output_tail": tail})
                say(f"seed {s}: artms-sod-replay exit {rc}: {tail.splitlines()[-1] if tail else ''}")
    done.sort()
    failures.sort(key=lambda f: f["seed"])
    observer = a.replay_options[a.replay_options.index("--observer") + 1] \
        if "--observer" in a.replay_options[:-1] else "SV4"
    data = {}  # target -> {seed: {t since the run's epoch: row}}
    period_s = 5700.0
    for s in list(done):
        try:
            summ = read_summary(os.path.join(a.campaign, f"seed_{s}"))
        except RunFolderError as e:
            failures.append({"seed": s, "exit_code": None, "output_tail": str(e)})
            done.remove(s)
            continue
        e0 = run_epoch_tt_ns(summ)
        period_s = float((summ.get("observers", {}).get(observer) or {}).get("period_s", period_s))
        for tgt, rows in read_replay(os.path.join(a.out, f"seed_{s}.csv")).items():
            data.setdefault(tgt, {})[s] = {t - e0: r for t, r in rows.items()}
    summary = {"campaign": os.path.abspath(a.campaign), "replay_options": a.replay_options, "seeds": done,
               "failures": failures, "targets": {}}
    print(f"{'target':<10} {'inside':>8} {'above':>7} {'below':>7} {'mean NEES':>9} {'after':>6}   "
          + " ".join(f"{'z2 ' + n:>10}" for n in ROE) + "   worst seed >3 / >5 sigma")
    for tgt in sorted(data):
        key = f"{observer}/{tgt}"
        after = a.after_orbit if a.after_orbit is not None else \
            float(((cs.get("targets") or {}).get(key) or {}).get("after_orbit") or 0.0)
        st = target_stats(data[tgt], after, period_s)
        summary["targets"][key] = st
        if st:
            print(f"{key:<10} {100 * st['frac_inside_band']:7.1f}% {100 * st['frac_above_band']:6.1f}% "
                  f"{100 * st['frac_below_band']:6.1f}% {st['mean_nees']:9.2f} {after:6.2f}   "
                  + " ".join(f"{x:10.2f}" for x in st["mean_z2_per_roe"])
                  + f"   {100 * st['worst_seed_frac_beyond_3sigma']:.1f} % / "
                    f"{100 * st['worst_seed_frac_beyond_5sigma']:.1f} %")
            sp = st["nees_spread"]
            if sp:
                lo, hi = st["band_95"]
                print(f"{'':<10} the average NEES's variance {sp['variance_of_average']:.2f} "
                      f"({sp['variance_with_runs_shifted']:.2f} with each run shifted in time): a common part of sd "
                      f"{sp['common_sd']:.2f} (band half-width {(hi - lo) / 2:.2f})")
            if st["mean_z2_per_principal_direction"]:
                print(f"{'':<10} (error/1-sigma)^2 along the principal directions, thinnest first: "
                      + " ".join(f"{x:.2f}" for x in st["mean_z2_per_principal_direction"]))
    with open(os.path.join(a.out, "replay_summary.json"), "w") as f:
        json.dump(summary, f, indent=1, sort_keys=True)
    for fl in failures:
        print(f"failed: seed {fl['seed']}: exit {fl['exit_code']}")
    print(f"summary: {os.path.join(a.out, 'replay_summary.json')}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
