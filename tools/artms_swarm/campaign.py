#!/usr/bin/python3
"""Campaign of one scenario over seeds: run them in parallel, then NEES consistency and statistics.

usage: campaign.py SCENARIO.yaml --seeds N (--orbits X | --duration 6h) --out DIR
                   [--first-seed 1] [--jobs J] [--in-process | --dds] [--bin build/bin] [--rerun]
                   [--from-orbit X] [--init-within-orbits X] [--epoch-window D]
                   [--dask-local N | --dask-scheduler tcp://HOST:PORT]

Each seed s is `artms-swarm run SCENARIO --seed s (--orbits X | --duration D) --out DIR/seed_<s>`
(with --in-process by default; --dds runs the multi-process DDS swarm; with
--epoch-window D each seed also draws its epoch within D after the
scenario's, so that the seeds fly over different parts of the world and the
NEES band compares independent worlds; the seeds are compared at the same
time since their own epoch). --jobs
seeds run at a time on this machine, or each seed is one task of a Dask
cluster: --dask-local N starts a LocalCluster of N single-thread workers on
127.0.0.1 (no dashboard), --dask-scheduler submits to a running scheduler
whose workers see the same paths. Progress on stderr; a failed seed is
recorded (exit code, last lines of DIR/logs/seed_<s>.log) and the others go on.

A seed folder is reused only if its campaign_run.json (written after the
seed succeeded) holds the same scenario sha256, span, seed and mode and its
summary.json gives every process exit code 0; any other seed folder is
deleted and run again (--rerun: always).

Writes DIR/campaign_summary.json (the same for the same seeds whatever ran
them), DIR/campaign_timing.json (wall times, reuse, hosts),
DIR/campaign_nees_<observer>_<target>.png and
DIR/campaign_error_<observer>_<target>.png. Per observer and target: the NEES
of the six ROE averaged over the runs at every navigation step against the
two-sided 95 % band of that average (chi-square with 6R degrees of freedom
divided by R, R = runs), the fraction of steps inside it after the latest and
after the median convergence (the second half of the run when a run never
converged), the mean NEES there; the final a*dlambda error and 1-sigma in % of
range, convergence orbits and the seeds that never converged, each seed's
fraction within 3 sigma; and the failures. Exit status 0 when every seed ran,
1 when one failed, 2 on a usage error.
Needs Debian's python3-numpy, python3-scipy, python3-matplotlib; python3-distributed for --dask-*.
"""
import argparse
import concurrent.futures
import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
import threading
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "python"))
from artms_tools.runfolder import (ROE_NAMES, RunFolderError, observer_nees, read_summary, target_nees,  # noqa: E402
                                   target_nis, target_normalised_errors, target_principal_errors)

RECORD = "campaign_run.json"
TAIL_LINES = 20
NIS_NOTE = ("per target (entry 'nis'): every bearing update's normalised innovation square (2 dof), from "
            "nav/targets.csv's cumulative bearing_nis_sum / bearing_updates; at each step the updates of all runs "
            "are pooled: mean NIS = sum / N against the two-sided 95 % band chi2(2N) / N")
NIS_MISSING = ("NIS is not recorded in these run folders (nav/targets.csv has no bearing_nis_sum column: made "
               "before issue 15), so no NIS band is computed")


_SAY = threading.Lock()


def say(msg, tool="campaign"):
    """A progress line on stderr (whole lines, also from worker threads), prefixed with the tool's name."""
    with _SAY:
        sys.stderr.write(f"{tool}: {msg}\n")
        sys.stderr.flush()


# ---------------------------------------------------------------- one seed (also a Dask task)
# Standard library only: Dask ships run_seed to its workers by value.

def seed_problem(seed_dir, seed):
    """Why a finished seed folder is not a good run (None when it is): summary.json missing, unreadable,
    for another seed, or a process with a non-zero exit code."""
    path = os.path.join(seed_dir, "summary.json")
    try:
        with open(path) as f:
            s = json.load(f)
    except FileNotFoundError:
        return "no summary.json"
    except (OSError, ValueError) as e:
        return f"summary.json unreadable ({e})"
    if not isinstance(s, dict) or not isinstance(s.get("processes"), list):
        return "summary.json has no processes list"
    if s.get("seed") != seed:
        return f"summary.json is for seed {s.get('seed')}"
    bad = [p for p in s["processes"] if not isinstance(p, dict) or p.get("exit_code") != 0]
    if bad:
        return "processes with a non-zero exit code: " + ", ".join(
            f"{p.get('name')} {p.get('exit_code')}" if isinstance(p, dict) else str(p) for p in bad)
    if not os.path.isfile(os.path.join(seed_dir, "eval", "targets.csv")):
        return "no eval/targets.csv (the evaluation against truth did not run)"
    return None


def claim_dds_domain():
    """A DDS domain in 201..230 that no other campaign seed of this host holds (flock on a file under
    /tmp, released when the returned file is closed). The launcher picks 1..200 from its pid when
    ARTMS_DDS_DOMAIN is unset, so parallel seeds never share a domain with each other or with it."""
    import fcntl
    import tempfile
    d = os.path.join(tempfile.gettempdir(), "artms-dds-domains")
    os.makedirs(d, exist_ok=True)
    while True:
        for dom in range(201, 231):
            f = open(os.path.join(d, f"{dom}.lock"), "a")
            try:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return f, dom
            except BlockingIOError:
                f.close()
        time.sleep(1.0)


def run_seed(job):
    """Runs one seed: artms-swarm into job['dir'], output to job['log']; after a clean run writes
    campaign_run.json (job['record']). Returns a result dict (seed, exit_code, ok, problem, wall_s, host, tail)."""
    import socket
    t0 = time.monotonic()
    env = dict(os.environ)
    lock = None
    rc, problem = None, None
    try:
        if job["record"]["mode"] == "dds":
            lock, domain = claim_dds_domain()
            env["ARTMS_DDS_DOMAIN"] = str(domain)
        os.makedirs(os.path.dirname(job["log"]), exist_ok=True)
        with open(job["log"], "wb") as log:
            rc = subprocess.run(job["cmd"], stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                env=env).returncode
    except OSError as e:
        problem = f"could not run {job['cmd'][0]}: {e}"
    finally:
        if lock is not None:
            lock.close()
    if rc == 0:
        problem = seed_problem(job["dir"], job["seed"])
        if problem is None:
            tmp = os.path.join(job["dir"], RECORD + ".tmp")
            with open(tmp, "w") as f:
                json.dump(job["record"], f, indent=1, sort_keys=True)
                f.write("\n")
            os.replace(tmp, os.path.join(job["dir"], RECORD))
    elif rc is not None:
        problem = f"artms-swarm exit code {rc}"
    tail = []
    if problem is not None:
        try:
            with open(job["log"], errors="replace") as f:
                tail = [line.rstrip("\n") for line in f.readlines()[-TAIL_LINES:]]
        except OSError:
            pass
    return {"seed": job["seed"], "exit_code": rc, "ok": problem is None, "problem": problem,
            "wall_s": time.monotonic() - t0, "host": socket.gethostname(), "tail": tail}


# ---------------------------------------------------------------- the campaign

def parse_args(argv):
    ap = argparse.ArgumentParser(prog="campaign.py", description=__doc__.split("\n")[0])
    ap.add_argument("scenario", help="scenario YAML")
    ap.add_argument("--seeds", type=int, required=True, help="number of seeds")
    ap.add_argument("--first-seed", type=int, default=1, help="first seed (default 1): seeds first..first+N-1")
    span = ap.add_mutually_exclusive_group(required=True)
    span.add_argument("--orbits", type=float, help="simulated span in orbits (artms-swarm run --orbits)")
    span.add_argument("--duration", help="simulated span (6h, 1d, seconds; artms-swarm run --duration)")
    ap.add_argument("--out", required=True, help="campaign folder: DIR/seed_<s>/, DIR/logs/, DIR/campaign_*")
    ap.add_argument("--jobs", type=int, help="seeds run at a time on this machine (default 1)")
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--in-process", dest="mode", action="store_const", const="in-process",
                      help="each seed in one process without DDS (the default; falls back to --dds with a "
                           "warning when artms-swarm has no --in-process)")
    mode.add_argument("--dds", dest="mode", action="store_const", const="dds",
                      help="each seed as the multi-process DDS swarm (loopback, one DDS domain per seed)")
    ap.add_argument("--bin", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "build", "bin"),
                    help="folder of artms-swarm (default: build/bin of this source tree)")
    ap.add_argument("--rerun", action="store_true", help="run every seed again, even reusable ones")
    ap.add_argument("--seed-plots", action="store_true",
                    help="also draw every seed's own plots (artms-report, ~3 s a seed); by default only the "
                         "campaign's plots are drawn (artms-swarm run --no-report)")
    ap.add_argument("--init-within-orbits", type=float, metavar="X",
                    help="count a seed initialised when its first estimate of a target came within X orbits "
                         "(mode 2: BOD's autonomous initialisation; default: at any time)")
    ap.add_argument("--from-orbit", type=float, metavar="X",
                    help="also report the fraction of steps inside the band from orbit X on")
    ap.add_argument("--epoch-window", metavar="D",
                    help="each seed draws its epoch within D after the scenario's (artms-swarm run --epoch-window; "
                         "24h: each seed over its own part of the geopotential, the Sun where it was)")
    ap.add_argument("--phase-window-deg", type=float, metavar="DEG",
                    help="each seed draws its orbit phase within DEG (artms-swarm run --phase-window-deg; 360: "
                         "each seed from its own point of the orbit, so that the latitudes, star fields and Sun "
                         "phase it meets at a given time differ too)")
    dask = ap.add_mutually_exclusive_group()
    dask.add_argument("--dask-local", type=int, metavar="N",
                      help="run the seeds on a Dask LocalCluster of N workers bound to 127.0.0.1")
    dask.add_argument("--dask-scheduler", metavar="ADDRESS",
                      help="submit the seeds to a running Dask scheduler (tcp://HOST:PORT); its workers must "
                           "see SCENARIO, --bin and --out at the same paths")
    a = ap.parse_args(argv)
    if a.seeds < 1:
        ap.error("--seeds must be at least 1")
    if a.jobs is not None and a.jobs < 1:
        ap.error("--jobs must be at least 1")
    if a.dask_local is not None and a.dask_local < 1:
        ap.error("--dask-local must be at least 1")
    if a.orbits is not None and not (a.orbits > 0 and math.isfinite(a.orbits)):
        ap.error("--orbits must be positive")
    if a.phase_window_deg is not None and not 0.0 <= a.phase_window_deg <= 360.0:
        ap.error("--phase-window-deg must lie in [0, 360]")
    return a


def supports_in_process(swarm):
    try:
        r = subprocess.run([swarm, "run", "--help"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return "--in-process" in r.stdout + r.stderr


def reuse_verdict(seed_dir, record):
    """(reusable, why): whether DIR/seed_<s> can be kept for this record, and why not."""
    path = os.path.join(seed_dir, RECORD)
    try:
        with open(path) as f:
            old = json.load(f)
    except FileNotFoundError:
        return False, f"no {RECORD} (an unfinished run, or one made by another tool)"
    except (OSError, ValueError) as e:
        return False, f"{RECORD} unreadable ({e})"
    if old != record:
        what = {"scenario_sha256": "the scenario file changed", "span": "another span", "seed": "another seed",
                "mode": "another run mode", "epoch_window_s": "another epoch window",
                "phase_window_deg": "another phase window"}
        keys = sorted(set(old) | set(record) if isinstance(old, dict) else set(record))
        diff = [k for k in keys if not isinstance(old, dict) or old.get(k) != record.get(k)]

        def show(v):
            return v[:12] + "..." if isinstance(v, str) and len(v) == 64 else json.dumps(v)
        if not diff:  # the same values, keys missing: a record written before they existed
            missing = sorted(set(record) - set(old)) if isinstance(old, dict) else []
            return False, f"{RECORD} predates {', '.join(missing) or 'this campaign.py'}"
        return False, f"{RECORD} differs: " + "; ".join(
            f"{k} {show(old.get(k) if isinstance(old, dict) else None)} -> {show(record.get(k))}"
            + (f" ({what[k]})" if k in what else "") for k in diff)
    problem = seed_problem(seed_dir, record["seed"])
    if problem:
        return False, problem
    return True, ""


class Progress:
    def __init__(self, total):
        self.total, self.done, self.failed = total, 0, 0
        self.lock = threading.Lock()

    def started(self, seed):
        say(f"seed {seed} started")

    def finished(self, res):
        with self.lock:
            self.done += 1
            self.failed += not res["ok"]
            counts = f"[{self.done}/{self.total} done, {self.failed} failed]"
        if res["ok"]:
            say(f"seed {res['seed']} finished in {res['wall_s']:.1f} s {counts}")
        else:
            tail = "\n".join("    " + line for line in res["tail"])
            say(f"seed {res['seed']} FAILED after {res['wall_s']:.1f} s: {res['problem']} {counts}"
                + (f"; last lines of its output:\n{tail}" if tail else ""))


def run_local(jobs, n_jobs, progress):
    results = []
    ex = concurrent.futures.ThreadPoolExecutor(max_workers=n_jobs)

    def one(job):  # in a worker thread: "finished" is said before this thread starts the next seed
        progress.started(job["seed"])
        try:
            res = run_seed(job)
        except Exception as e:  # a bug in run_seed: record it, go on
            res = {"seed": job["seed"], "exit_code": None, "ok": False, "problem": f"{type(e).__name__}: {e}",
                   "wall_s": 0.0, "host": None, "tail": []}
        progress.finished(res)
        return res

    futs = [ex.submit(one, j) for j in jobs]
    try:
        for f in concurrent.futures.as_completed(futs):
            results.append(f.result())
    except KeyboardInterrupt:
        say("interrupted: cancelling the seeds not started")
        ex.shutdown(wait=False, cancel_futures=True)
        raise
    ex.shutdown()
    return results


def run_dask(jobs, args, progress):
    try:
        import logging
        from distributed import Client, LocalCluster, as_completed
    except ImportError as e:
        raise SystemExit(f"campaign: --dask-* needs Debian's python3-distributed (scripts/install-deps.sh): {e}")
    cluster = None
    if args.dask_local is not None:
        # Loopback only: scheduler, nannies and workers listen on 127.0.0.1. Scheduler and workers
        # always start an HTTP server (health, metrics) and bind it to every interface unless given
        # an address: 127.0.0.1 with a free port, and the scheduler's dashboard off.
        cluster = LocalCluster(n_workers=args.dask_local, threads_per_worker=1, processes=True, host="127.0.0.1",
                               scheduler_port=0, dashboard_address=None, worker_dashboard_address="127.0.0.1:0",
                               scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
                               silence_logs=logging.ERROR)
        client = Client(cluster)
        say(f"Dask LocalCluster at {cluster.scheduler_address}, {args.dask_local} workers")
    else:
        try:
            client = Client(args.dask_scheduler, timeout=30)
        except (OSError, TimeoutError, ValueError) as e:
            raise SystemExit(f"campaign: cannot reach the Dask scheduler {args.dask_scheduler}: {e}")
        say(f"Dask scheduler {args.dask_scheduler}: {len(client.scheduler_info().get('workers', {}))} workers")
    results, futs = [], {}
    try:
        for j in jobs:
            f = client.submit(run_seed, j, pure=False, key=f"artms-seed-{j['seed']}-{os.getpid()}-{time.time_ns()}")
            futs[f] = j
            say(f"seed {j['seed']} submitted")
        for f in as_completed(list(futs)):
            try:
                res = f.result()
            except Exception as e:
                res = {"seed": futs[f]["seed"], "exit_code": None, "ok": False, "problem": f"Dask task: {type(e).__name__}: {e}",
                       "wall_s": 0.0, "host": None, "tail": []}
            progress.finished(res)
            results.append(res)
    except KeyboardInterrupt:
        say("interrupted: cancelling the Dask tasks")
        client.cancel(list(futs))
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return results


def main(argv=None):
    args = parse_args(argv)
    t_start = time.monotonic()
    scenario = os.path.abspath(args.scenario)
    try:
        with open(scenario, "rb") as f:
            scenario_sha = hashlib.sha256(f.read()).hexdigest()
    except OSError as e:
        say(f"cannot read the scenario: {e}")
        return 2
    swarm = os.path.join(os.path.abspath(args.bin), "artms-swarm")
    if not os.access(swarm, os.X_OK):
        say(f"no artms-swarm in {os.path.abspath(args.bin)} (build first, or give --bin)")
        return 2
    v = subprocess.run([swarm, "validate", scenario], capture_output=True, text=True)
    if v.returncode != 0:
        say(f"the scenario does not validate:\n{v.stdout}{v.stderr}")
        return 2

    mode = args.mode or "in-process"
    if mode == "in-process" and not supports_in_process(swarm):
        say(f"WARNING: `{swarm} run --help` does not mention --in-process (this build has no in-process "
            f"runner yet): every seed runs as the multi-process DDS swarm instead (loopback, one DDS domain per "
            f"seed); campaign_run.json records mode dds, so these seeds run again once --in-process exists")
        mode = "dds"
    span = {"orbits": float(args.orbits)} if args.orbits is not None else {"duration": args.duration}
    window_s = None
    if args.epoch_window is not None:
        try:
            window_s = duration_s(args.epoch_window)
        except ValueError as e:
            say(f"--epoch-window: {e}")
            return 2
    span_args = ["--orbits", repr(float(args.orbits))] if args.orbits is not None else ["--duration", args.duration]
    out = os.path.abspath(args.out)
    os.makedirs(os.path.join(out, "logs"), exist_ok=True)
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    if args.dask_local is not None or args.dask_scheduler:
        executor = "dask-local" if args.dask_local is not None else "dask-scheduler"
        if args.jobs is not None:
            say("--jobs is ignored with --dask-*: the cluster's workers set the parallelism")
    else:
        executor = "local"
    n_jobs = args.jobs or 1
    say(f"{len(seeds)} seeds ({seeds[0]}..{seeds[-1]}) of {args.scenario}, {' '.join(span_args)}, mode {mode}, "
        + (f"{n_jobs} at a time" if executor == "local" else executor))

    jobs, reused = [], []
    for s in seeds:
        d = os.path.join(out, f"seed_{s}")
        record = {"scenario_sha256": scenario_sha, "span": span, "seed": s, "mode": mode,
                  "seed_plots": bool(args.seed_plots), "epoch_window_s": window_s}
        if args.phase_window_deg is not None:  # absent otherwise, so that earlier seed folders stay reusable
            record["phase_window_deg"] = args.phase_window_deg
        if os.path.exists(d):
            ok, why = (False, "--rerun") if args.rerun else reuse_verdict(d, record)
            if ok:
                say(f"seed {s}: reused seed_{s} (same scenario sha256, span, seed and mode; exit codes 0)")
                reused.append(s)
                continue
            say(f"seed {s}: seed_{s} is stale ({why}): deleting it and re-running the seed")
            shutil.rmtree(d)
        cmd = [swarm, "run", scenario, "--seed", str(s)] + span_args + ["--out", d]
        if window_s is not None:
            cmd += ["--epoch-window", repr(window_s)]
        if args.phase_window_deg is not None:
            cmd += ["--phase-window-deg", repr(args.phase_window_deg)]
        if mode == "in-process":
            cmd.append("--in-process")
        if not args.seed_plots:
            cmd.append("--no-report")
        jobs.append({"seed": s, "cmd": cmd, "dir": d, "log": os.path.join(out, "logs", f"seed_{s}.log"),
                     "record": record})

    progress = Progress(len(jobs))
    results = []
    if jobs:
        try:
            results = run_local(jobs, n_jobs, progress) if executor == "local" else run_dask(jobs, args, progress)
        except KeyboardInterrupt:
            return 130
    wall = time.monotonic() - t_start
    failed = sorted((r for r in results if not r["ok"]), key=lambda r: r["seed"])
    ok_seeds = sorted(reused + [r["seed"] for r in results if r["ok"]])
    say(f"{len(results)} seeds run, {len(reused)} reused, {len(failed)} failed, in {wall:.1f} s")

    meta = {"scenario_file": args.scenario, "scenario_sha256": scenario_sha, "span": span, "mode": mode,
            "seeds_requested": seeds, "from_orbit": args.from_orbit, "init_within_orbits": args.init_within_orbits,
            "epoch_window_s": window_s}
    failures = [{"seed": r["seed"], "exit_code": r["exit_code"], "problem": r["problem"],
                 "log": os.path.join("logs", f"seed_{r['seed']}.log"), "output_tail": r["tail"]} for r in failed]
    try:
        summary = summarise(out, ok_seeds, meta, failures)
    except (RunFolderError, OSError) as e:
        say(f"cannot summarise: {e}")
        return 1
    with open(os.path.join(out, "campaign_summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
        f.write("\n")
    by_seed = {r["seed"]: r for r in results}
    timing = {"wall_s": wall, "executor": executor, "jobs": n_jobs if executor == "local" else args.dask_local,
              "seeds": {str(s): ({"reused": True} if s in reused else
                                 {"reused": False, "wall_s": by_seed[s]["wall_s"], "host": by_seed[s]["host"],
                                  "ok": by_seed[s]["ok"]}) for s in seeds}}
    with open(os.path.join(out, "campaign_timing.json"), "w") as f:
        json.dump(timing, f, indent=1)
        f.write("\n")
    print_table(summary, out)
    print_absolute(summary)
    return 1 if failed else 0


# ---------------------------------------------------------------- summary and plots

def duration_s(text):
    """Seconds of a duration as artms-swarm reads it: 90s, 30m, 6h, 1.5d or plain seconds (>= 0)."""
    t = str(text).strip()
    scale = {"s": 1.0, "m": 60.0, "h": 3600.0, "d": 86400.0}.get(t[-1:], None)
    number = t[:-1] if scale else t
    try:
        v = float(number) * (scale or 1.0)
    except ValueError:
        raise ValueError(f"invalid duration {text!r} (expected e.g. 90s, 30m, 6h, 1.5d or seconds)") from None
    if not math.isfinite(v) or v < 0:
        raise ValueError(f"invalid duration {text!r} (expected e.g. 90s, 30m, 6h, 1.5d or seconds)")
    return v


def run_epoch_tt_ns(summary):
    """The run's epoch (TT ns since J2000) from summary.json; 0 for run folders that predate it (their
    seeds all share the scenario's epoch, so their absolute times line up as they are)."""
    return int(summary.get("epoch", {}).get("tt_ns", 0))


def since_epoch(series, e0):
    """{t_tt_ns: x} keyed by the time since the run's epoch instead (seeds drawn with --epoch-window start
    at different instants and are compared at the same time since their start)."""
    return {t - e0: x for t, x in series.items()}


def _stats(values):
    v = [x for x in values if isinstance(x, (int, float)) and math.isfinite(x)]
    import numpy as np
    return {"median": float(np.median(v)) if v else None, "max": float(max(v)) if v else None, "per_seed": values}


def summarise(out, seeds, meta, failures):
    """campaign_summary.json's content; writes the plots. The NEES part is monte_carlo.py's computation."""
    import warnings
    import numpy as np
    from scipy.stats import chi2
    nees = {}      # (obs, tgt) -> list over runs of {t: nees}
    conv = {}      # (obs, tgt) -> list of convergence orbits (None if never)
    per_seed = {}  # (obs, tgt) -> {seed: summary.json target entry}
    period = None
    name = None
    nis = {}  # (obs, tgt) -> list over runs of {t: (cumulative nis sum, cumulative updates)}
    zs = {}   # (obs, tgt) -> list over runs of {t: [error / 1-sigma per ROE]}
    pz = {}   # (obs, tgt) -> list over runs of {t: [(error / 1-sigma)^2 along P's principal directions]}
    windows = set()  # the runs' epoch windows (summary.json epoch.window_s), s
    phases = set()   # the runs' orbit phase windows (summary.json orbit_phase.window_deg), deg
    for s in seeds:
        d = os.path.join(out, f"seed_{s}")
        summ = read_summary(d)
        e0 = run_epoch_tt_ns(summ)
        windows.add(float((summ.get("epoch") or {}).get("window_s", 0.0)))
        phases.add(float((summ.get("orbit_phase") or {}).get("window_deg", 0.0)))
        name = name or summ.get("scenario")
        for obs, o in summ.get("observers", {}).items():
            period = o.get("period_s", period)
            for tgt, t in o.get("targets", {}).items():
                conv.setdefault((obs, tgt), []).append(t.get("convergence_orbits"))
                per_seed.setdefault((obs, tgt), {})[s] = t
        for k, v in target_nees(d).items():
            nees.setdefault(k, []).append(since_epoch(v, e0))
        for k, v in target_nis(d).items():
            nis.setdefault(k, []).append(since_epoch(v, e0))
        for k, v in target_normalised_errors(d).items():
            zs.setdefault(k, []).append(since_epoch(v, e0))
        for k, v in target_principal_errors(d).items():
            pz.setdefault(k, []).append(since_epoch(v, e0))
    R = len(seeds)
    windows = sorted(windows)
    phases = sorted(phases)
    meta = {**meta, "epoch_window_s": windows[0] if len(windows) == 1 else windows,
            "phase_window_deg": phases[0] if len(phases) == 1 else phases}
    out_json = {"scenario": name, **meta, "seeds": seeds, "runs": R,
                "band_95": [float(chi2.ppf(0.025, 6 * R) / R), float(chi2.ppf(0.975, 6 * R) / R)] if R else None,
                "targets": {}, "nis_note": NIS_NOTE if nis else NIS_MISSING,
                "failures": failures}
    for key in sorted(set(nees) | set(per_seed)):
        obs, tgt = key
        entry = {"observer": obs, "target": tgt}
        runs = nees.get(key, [])
        cs = conv.get(key, [])
        if runs:
            # monte_carlo.py's computation, unchanged (R is the number of runs holding this pair).
            Rt = len(runs)
            lo, hi = chi2.ppf(0.025, 6 * Rt) / Rt, chi2.ppf(0.975, 6 * Rt) / Rt
            times = sorted(set.intersection(*[set(r) for r in runs]))
            if times:
                M = np.array([[r[t] for t in times] for r in runs])
                ok_cols = np.all(np.isfinite(M), axis=0)
                t0 = times[0]
                orb = (np.array(times) - t0) * 1e-9 / (period or 5700.0)
                start = max(cs) if cs and all(c is not None for c in cs) else orb[-1] / 2
                sel = (orb >= start) & ok_cols
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)  # steps where every run has NaN
                    avg = np.nanmean(M, axis=0)
                inside = (avg >= lo) & (avg <= hi)
                frac = float(np.mean(inside[sel])) if sel.any() else None
                done = [c for c in cs if c is not None]
                start_med = float(np.median(done)) if done else orb[-1] / 2
                sel_med = (orb >= start_med) & ok_cols
                frac_med = float(np.mean(inside[sel_med])) if sel_med.any() else None
                if meta.get("from_orbit") is not None:
                    sel_from = (orb >= meta["from_orbit"]) & ok_cols
                    entry["frac_inside_band_from_orbit"] = float(np.mean(inside[sel_from])) if sel_from.any() else None
                entry.update({
                    "runs": Rt, "band_95": [float(lo), float(hi)],
                    "after_orbit": float(start), "steps": int(sel.sum()), "frac_inside_band": frac,
                    "frac_below_band": float(np.mean(avg[sel] < lo)) if sel.any() else None,
                    "frac_above_band": float(np.mean(avg[sel] > hi)) if sel.any() else None,
                    "mean_nees_after": float(np.mean(avg[sel])) if sel.any() else None,
                    "after_median_orbit": start_med, "steps_after_median": int(sel_med.sum()),
                    "frac_inside_band_after_median": frac_med})
                plot_nees(out, obs, tgt, orb, avg, lo, hi, start, start_med, frac, frac_med, Rt)
                entry["nis"] = nis_entry(nis.get(key, []), t0, period or 5700.0, start, start_med)
                entry["nees_spread"] = nees_spread_entry(M[:, sel]) if sel.any() else None
                entry["common_to_every_seed"] = common_mode_entry(zs.get(key, []), times, sel)
                entry["by_direction"] = direction_entry(zs.get(key, []), pz.get(key, []), times, sel)
        entry["convergence_orbits"] = cs
        ps = per_seed.get(key, {})
        tg = [ps.get(s, {}) for s in seeds]
        conv_seed = [t.get("convergence_orbits") for t in tg]
        never = [s for s, t in zip(seeds, tg) if t and t.get("convergence_orbits") is None]
        done = [c for c in conv_seed if c is not None]
        frac3 = [t.get("frac_within_3sigma") for t in tg]
        mins = [min(f.values()) if isinstance(f, dict) and f else None for f in frac3]
        entry.update({
            "final_dlambda_error_pct": _stats([t.get("final_dlambda_error_pct") for t in tg]),
            "final_dlambda_sigma_pct": _stats([t.get("final_dlambda_sigma_pct") for t in tg]),
            "convergence": {"median_orbits": float(np.median(done)) if done else None,
                            "max_orbits": float(max(done)) if done else None,
                            "never_converged": len(never), "never_converged_seeds": never,
                            "per_seed": conv_seed},
            "frac_within_3sigma": {"per_seed": frac3, "min_per_seed": mins,
                                   "seeds_min_at_least_0.99": sum(1 for m in mins if m is not None and m >= 0.99)},
            "initialisation": initialisation_entry(seeds, tg, meta.get("init_within_orbits")),
            "nees_mean_per_seed": [t.get("nees_mean") for t in tg],
            # Over-confidence at a glance: the worst seed's share of steps beyond 3 and 5 sigma.
            "worst_seed_frac_beyond_3sigma": _stats([t.get("frac_beyond_3sigma") for t in tg])["max"],
            "worst_seed_frac_beyond_5sigma": _stats([t.get("frac_beyond_5sigma") for t in tg])["max"],
            # ... and the longest stretch any seed spent beyond 5 sigma while reporting the target healthy.
            "worst_seed_beyond_5sigma_reported_healthy": worst_healthy_stretch(seeds, tg),
            "seeds_with_target": [s for s, t in zip(seeds, tg) if t and t.get("estimated", True)],
        })
        plot_errors(out, obs, tgt, seeds, tg)
        plot_initial_errors(out, obs, tgt, tg)
        out_json["targets"][f"{obs}/{tgt}"] = entry
    out_json["absolute"] = absolute_entries(out, seeds, meta, period or 5700.0)
    return out_json


COMMON_NOTE = ("The band assumes independent runs. Errors common to every seed (the same world, geometry "
               "and camera in each unless the epoch is drawn per seed, --epoch-window) do not average out: per ROE, the RMS over the "
               "steps after the latest convergence of the seed-mean of error / 1-sigma, against "
               "total / sqrt(runs) for independent runs (ratio 1); a ratio well above 1 means the band test "
               "measures the common error of one world, not the filter's consistency over worlds.")


def common_mode_entry(runs, times, sel):
    """Per ROE: the RMS of the seed-mean normalised error over the selected steps, the RMS of the
    normalised error itself, and their ratio to the independent-runs expectation (COMMON_NOTE)."""
    import numpy as np
    if not runs or not len(times) or not sel.any():
        return None
    ts = [t for t, keep in zip(times, sel) if keep]
    if not all(all(t in r for t in ts) for r in runs):
        return None
    Z = np.array([[r[t] for t in ts] for r in runs], dtype=float)  # runs x steps x 6
    R = Z.shape[0]
    with np.errstate(invalid="ignore"):
        mean_z = np.nanmean(Z, axis=0)
        common = np.sqrt(np.nanmean(mean_z ** 2, axis=0))
        total = np.sqrt(np.nanmean(Z ** 2, axis=(0, 1)))
        ratio = common / (total / math.sqrt(R))
    return {"roe": list(ROE_NAMES), "rms_seed_mean_z": [float(x) for x in common],
            "rms_z": [float(x) for x in total], "ratio_to_independent": [float(x) for x in ratio],
            "note": COMMON_NOTE}


SPREAD_NOTE = ("The R-run average NEES over the steps after the latest convergence: its variance over those "
               "steps, against the same variance when each run's series is shifted in time by its own random lag "
               "(circularly within the steps; the mean over 50 draws): the shifts keep every run's own scatter and "
               "its correlation in time and take away only what moves the runs together with the time since the "
               "start. The rest is that common part (sd = its square root; 0 when the rest is negative). The band "
               "assumes none: a common part of sd comparable to the band's half-width puts whole stretches outside "
               "it, above and below, while the mean NEES is right.")


def nees_spread_entry(M, draws=50):
    """M: runs x steps NEES (NaN allowed). Variance of the run-average over the steps, the same with every run
    shifted by its own random circular lag (the mean over `draws`), and the common part's sd (SPREAD_NOTE);
    None with fewer than 2 runs or 4 steps."""
    import numpy as np
    M = np.asarray(M, dtype=float)
    if M.ndim != 2 or M.shape[0] < 2 or M.shape[1] < 4:
        return None
    M = M[:, np.all(np.isfinite(M), axis=0)]  # steps every run has
    R, n = M.shape
    if n < 4:
        return None
    var_avg = float(np.var(M.mean(axis=0), ddof=1))
    rng = np.random.default_rng(20240508)
    rows, cols = np.arange(R)[:, None], np.arange(n)[None, :]
    shifted = [float(np.var(M[rows, (cols + rng.integers(0, n, R)[:, None]) % n].mean(axis=0), ddof=1))
               for _ in range(draws)]
    base = float(np.mean(shifted))
    return {"variance_of_average": var_avg, "variance_with_runs_shifted": base,
            "common_sd": float(math.sqrt(max(var_avg - base, 0.0))), "note": SPREAD_NOTE}


DIRECTION_NOTE = ("Mean (error / 1-sigma)^2 over the runs and the steps after the latest convergence, per ROE "
                  "and along the covariance's principal directions (thinnest first; nav/targets.csv's "
                  "covariance). Each is 1 for a consistent filter. A mean NEES inside the band with directions "
                  "well above and below 1 is a NEES that scatters more than chi2(6): the band test then fails on "
                  "both sides.")


def worst_healthy_stretch(seeds, tg):
    """The seed with the longest stretch beyond 5 sigma while reported healthy (summary.json's
    longest_beyond_5sigma_reported_healthy_orbits): {seed, orbits}, or None when no seed reports one."""
    best = None
    for s, t in zip(seeds, tg):
        v = (t or {}).get("longest_beyond_5sigma_reported_healthy_orbits")
        if v is not None and (best is None or v > best["orbits"]):
            best = {"seed": s, "orbits": float(v)}
    return best


def direction_entry(z_runs, p_runs, times, sel):
    """Mean squared normalised error per ROE and per principal direction of the covariance (DIRECTION_NOTE)."""
    import numpy as np
    ts = [t for t, keep in zip(times, sel) if keep]
    if not ts:
        return None
    out = {"roe": list(ROE_NAMES), "note": DIRECTION_NOTE}
    z = [r[t] for r in z_runs for t in ts if t in r]
    if z:
        with np.errstate(invalid="ignore"):
            out["mean_z2_per_roe"] = [float(x) for x in np.nanmean(np.array(z, dtype=float) ** 2, axis=0)]
    p = [r[t] for r in p_runs for t in ts if t in r]
    if p:
        out["mean_z2_per_principal_direction"] = [float(x) for x in np.nanmean(np.array(p, dtype=float), axis=0)]
        out["principal_steps"] = len(p)
    return out


def absolute_entries(out, seeds, meta, period_s):
    """Each observer's absolute orbit over the runs (navigation mode 4 above all): the average position NEES
    (3 dof) against its 95 % band chi2(3R)/R from `absolute_after_hours` on (default 6 h, issue 18), and the
    final position errors (median, max) from summary.json."""
    import numpy as np
    from scipy.stats import chi2
    runs, finals = {}, {}
    for s in seeds:
        d = os.path.join(out, f"seed_{s}")
        summ = read_summary(d)
        for obs, v in observer_nees(d).items():
            runs.setdefault(obs, []).append(since_epoch(v, run_epoch_tt_ns(summ)))
        for obs, o in summ.get("observers", {}).items():
            a = o.get("absolute", {})
            if a.get("final_pos_error_m") is not None:
                finals.setdefault(obs, []).append((a["final_pos_error_m"], a.get("initial_position_error_m"),
                                                   a.get("angles_only_fraction")))
    after_h = meta.get("absolute_after_hours", 6.0)
    entries = {}
    for obs, rs in sorted(runs.items()):
        R = len(rs)
        times = sorted(set.intersection(*[set(r) for r in rs]))
        if not times:
            continue
        M = np.array([[r[t] for t in times] for r in rs])
        h = (np.array(times) - times[0]) * 1e-9 / 3600.0
        avg = np.nanmean(M, axis=0) if np.isfinite(M).any() else np.full(len(times), np.nan)
        lo, hi = chi2.ppf(0.025, 3 * R) / R, chi2.ppf(0.975, 3 * R) / R
        sel = (h >= after_h) & np.isfinite(avg)
        inside = (avg >= lo) & (avg <= hi)
        f = finals.get(obs, [])
        entries[obs] = {
            "runs": R, "band_95": [float(lo), float(hi)], "after_hours": after_h, "steps": int(sel.sum()),
            "frac_inside_band": float(np.mean(inside[sel])) if sel.any() else None,
            "mean_nees_after": float(np.mean(avg[sel])) if sel.any() else None,
            "frac_above_band": float(np.mean(avg[sel] > hi)) if sel.any() else None,
            "final_position_error_m": _stats([x[0] for x in f]),
            "initial_position_error_m": _stats([x[1] for x in f]),
            "angles_only_fraction": _stats([x[2] for x in f]),
        }
        plt = _plt()
        plt.figure(figsize=(8, 3.5))
        plt.plot(h, avg, lw=0.8, label=f"average of {R} runs")
        plt.axhspan(lo, hi, color="tab:green", alpha=0.25, label=f"95 % band [{lo:.2f}, {hi:.2f}]")
        plt.axvline(after_h, color="k", ls=":", lw=0.8)
        plt.yscale("log")
        plt.xlabel("hours")
        plt.ylabel("position NEES (3 dof)")
        plt.title(f"{obs}: absolute position NEES")
        plt.legend(fontsize=8)
        plt.tight_layout()
        plt.savefig(os.path.join(out, f"absolute_nees_{_safe(obs)}.png"), dpi=110)
        plt.close()
    return entries


def initialisation_entry(seeds, tg, within_orbits):
    """The first estimate of each seed (mode 2: BOD's initialisation): when, its dlambda error against its
    own 1-sigma, and the seeds initialised within `within_orbits` (None: any time)."""
    first = [t.get("first_estimate_orbits") for t in tg]
    err = [t.get("initial_dlambda_error_pct") for t in tg]
    sig = [t.get("initial_dlambda_sigma_pct") for t in tg]
    in3 = [t.get("initial_within_3sigma") for t in tg]
    ok = [f is not None and (within_orbits is None or f <= within_orbits) for f in first]
    n = len(seeds)
    return {"within_orbits": within_orbits, "initialised": sum(ok), "seeds": n,
            "fraction_initialised": sum(ok) / n if n else None,
            "initial_within_3sigma": sum(1 for x in in3 if x), "fraction_initial_within_3sigma":
            sum(1 for x in in3 if x) / n if n else None,
            "first_estimate_orbits": first, "initial_dlambda_error_pct": err, "initial_dlambda_sigma_pct": sig,
            "not_initialised_seeds": [s for s, o in zip(seeds, ok) if not o]}


def plot_initial_errors(out, obs, tgt, tg):
    """Histogram of the first estimate's dlambda error in units of its own 1-sigma (plots/)."""
    z = [t["initial_dlambda_error_pct"] / t["initial_dlambda_sigma_pct"] for t in tg
         if t and t.get("initial_dlambda_sigma_pct")]
    if not z:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.hist(z, bins=[x * 0.5 for x in range(-10, 11)], color="tab:blue", edgecolor="black")
    for x in (-3, 3):
        ax.axvline(x, color="tab:red", linestyle="--")
    ax.set_xlabel("first estimate: a*dlambda error / 1-sigma")
    ax.set_ylabel("seeds")
    ax.set_title(f"{obs} -> {tgt}: {sum(1 for v in z if abs(v) <= 3)} of {len(z)} inside 3-sigma")
    fig.tight_layout()
    os.makedirs(os.path.join(out, "plots"), exist_ok=True)
    fig.savefig(os.path.join(out, "plots", f"initial_error_{obs}_{tgt}.png"), dpi=110)
    plt.close(fig)


def nis_entry(runs, t0, period_s, start, start_med):
    """Bearing NIS over the campaign: at every step, the updates of that step in every run pooled (sum S of
    their NIS, count N; each 2 dof), the step inside the 95 % band when chi2(2N).ppf(.025) <= S <= .ppf(.975);
    fractions of the steps with updates after the latest and the median convergence. None without data."""
    from scipy.stats import chi2
    if not runs:
        return None
    S, N = {}, {}
    for r in runs:
        prev = (0.0, 0)
        for t in sorted(r):
            s, n = r[t]
            if n > prev[1]:
                S[t] = S.get(t, 0.0) + (s - prev[0])
                N[t] = N.get(t, 0) + (n - prev[1])
            prev = (s, n)
    out = {}
    for label, after in (("after_latest_convergence", start), ("after_median_convergence", start_med)):
        steps = [t for t in sorted(N) if (t - t0) * 1e-9 / period_s >= after]
        if not steps:
            out[label] = None
            continue
        inside = [chi2.ppf(0.025, 2 * N[t]) <= S[t] <= chi2.ppf(0.975, 2 * N[t]) for t in steps]
        tot_s, tot_n = sum(S[t] for t in steps), sum(N[t] for t in steps)
        out[label] = {"after_orbit": float(after), "steps": len(steps), "updates": int(tot_n),
                      "mean_nis": tot_s / tot_n, "frac_inside_band": sum(inside) / len(inside)}
    return out


def _safe(name):
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in str(name)) or "_"


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_nees(out, obs, tgt, orb, avg, lo, hi, start, start_med, frac, frac_med, R):
    plt = _plt()
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
    plt.savefig(os.path.join(out, f"campaign_nees_{_safe(obs)}_{_safe(tgt)}.png"), dpi=120)
    plt.close()


def plot_errors(out, obs, tgt, seeds, tg):
    """Final a*dlambda error in % of range over the seeds, and every ROE's final error / 1-sigma."""
    import numpy as np
    plt = _plt()
    err = np.array([t.get("final_dlambda_error_pct") for t in tg if t.get("final_dlambda_error_pct") is not None],
                   dtype=float)
    z = []
    for t in tg:
        e, s = t.get("final_error_a_roe_m"), t.get("final_sigma_a_roe_m")
        if isinstance(e, list) and isinstance(s, list) and len(e) == len(s) == 6:
            z += [a / b for a, b in zip(e, s) if a is not None and b]
    z = np.array(z, dtype=float)
    err, z = err[np.isfinite(err)], z[np.isfinite(z)]
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    ax = axes[0]
    if err.size:
        ax.hist(err, bins=max(5, min(30, err.size)), color="0.4")
        ax.axvline(float(np.median(err)), color="tab:red", ls="--", lw=0.8, label=f"median {np.median(err):.3g} %")
        ax.legend(fontsize=8)
    ax.set_xlabel(r"final $|a\delta\lambda|$ error [% of range]"); ax.set_ylabel("seeds")
    ax.set_title(f"{obs} -> {tgt}: {err.size} of {len(seeds)} seeds", fontsize=9)
    ax = axes[1]
    if z.size:
        lim = max(4.0, float(np.max(np.abs(z))))
        ax.hist(z, bins=np.linspace(-lim, lim, 25), density=True, color="0.6", label="final error / 1-sigma, 6 ROE")
        x = np.linspace(-lim, lim, 200)
        ax.plot(x, np.exp(-x * x / 2) / math.sqrt(2 * math.pi), "k-", lw=0.8, label="N(0, 1)")
        ax.legend(fontsize=8)
    ax.set_xlabel("final error / 1-sigma"); ax.set_ylabel("density")
    ax.grid(alpha=0.3); axes[0].grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, f"campaign_error_{_safe(obs)}_{_safe(tgt)}.png"), dpi=120)
    plt.close(fig)


def print_absolute(s):
    for obs, a in s.get("absolute", {}).items():
        fe = a.get("final_position_error_m") or {}
        fr = a.get("frac_inside_band")
        print(f"absolute {obs}: position NEES after {a['after_hours']:g} h: mean "
              f"{a['mean_nees_after'] if a['mean_nees_after'] is None else round(a['mean_nees_after'], 2)}, "
              f"inside [{a['band_95'][0]:.2f}, {a['band_95'][1]:.2f}] on "
              f"{'-' if fr is None else f'{100 * fr:.1f} %'} of steps; final position error median "
              f"{fe.get('median')}, max {fe.get('max')} m")


def world_text(window_s, phase_deg=None):
    """What the campaign's seeds share of the world, from the runs' epoch and orbit phase windows."""
    if isinstance(phase_deg, list):
        phase = "; seeds with different orbit phase windows: " + ", ".join(f"{w:g} deg" for w in phase_deg)
    elif phase_deg:
        phase = f"; each seed's orbit phase drawn within {phase_deg:g} deg"
    else:
        phase = ""
    if isinstance(window_s, list):
        return ", seeds with different epoch windows: " + ", ".join(f"{w:g} s" for w in window_s) + phase
    if window_s:
        return (f", each seed's epoch drawn within {window_s / 3600:g} h of the scenario's (a world per seed)"
                + phase)
    if phase:
        return ", the scenario's epoch" + phase + " (a world per seed)"
    return ", one world for every seed (the scenario's epoch)"


def print_table(s, out):
    def f(v, spec):
        return spec.format(v) if isinstance(v, (int, float)) and math.isfinite(v) else "-"
    print(f"campaign {s['scenario']}: {s['runs']} of {len(s['seeds_requested'])} seeds "
          f"({len(s['failures'])} failed), band 95 % "
          + (f"[{s['band_95'][0]:.2f}, {s['band_95'][1]:.2f}]" if s["band_95"] else "-")
          + world_text(s.get("epoch_window_s"), s.get("phase_window_deg")))
    print(f"{'target':<10} {'inside latest':>13} {'(below':>7} {'above)':>7} {'inside median':>13} {'mean NEES':>9} "
          f"{'dl err % med':>12} {'(max)':>8} {'conv med':>8} {'(max)':>6} {'never':>5} {'mean NIS':>8} {'NIS inside':>10} "
          f"{'worst seed >3/5 sigma':>21}")
    for k, t in s["targets"].items():
        fr, frm = t.get("frac_inside_band"), t.get("frac_inside_band_after_median")
        lo, hi = t.get("frac_below_band"), t.get("frac_above_band")
        w3, w5 = t.get("worst_seed_frac_beyond_3sigma"), t.get("worst_seed_frac_beyond_5sigma")
        nis = (t.get("nis") or {}).get("after_latest_convergence")
        print(f"{k:<10} {f(fr and 100 * fr, '{:.1f} %'):>13} {f(lo is not None and 100 * lo, '{:.1f}'):>7} "
              f"{f(hi is not None and 100 * hi, '{:.1f}'):>7} {f(frm and 100 * frm, '{:.1f} %'):>13} "
              f"{f(t.get('mean_nees_after'), '{:.2f}'):>9} {f(t['final_dlambda_error_pct']['median'], '{:.3f}'):>12} "
              f"{f(t['final_dlambda_error_pct']['max'], '{:.3f}'):>8} {f(t['convergence']['median_orbits'], '{:.2f}'):>8} "
              f"{f(t['convergence']['max_orbits'], '{:.2f}'):>6} {t['convergence']['never_converged']:>5} "
              f"{f(nis and nis['mean_nis'], '{:.2f}'):>8} {f(nis and 100 * nis['frac_inside_band'], '{:.1f} %'):>10} "
              f"{f(w3 is not None and 100 * w3, '{:.1f} %'):>10} / {f(w5 is not None and 100 * w5, '{:.1f} %'):>8}")
    for k, t in s["targets"].items():
        w = t.get("worst_seed_beyond_5sigma_reported_healthy")
        if w and w["orbits"] > 0.0:
            print(f"{k}: seed {w['seed']} is beyond 5 sigma while reported healthy for {w['orbits']:.2f} orbits on end "
                  f"(the longest of the seeds)")
    for k, t in s["targets"].items():
        sp = t.get("nees_spread")
        if sp:
            lo, hi = t["band_95"]
            print(f"{k}: the {t['runs']}-run average NEES varies with variance {sp['variance_of_average']:.2f} "
                  f"({sp['variance_with_runs_shifted']:.2f} with each run shifted in time): a part common to the "
                  f"runs of sd {sp['common_sd']:.2f}, against the band's half-width {(hi - lo) / 2:.2f}")
    for k, t in s["targets"].items():
        c = t.get("common_to_every_seed")
        if c:
            print(f"{k}: errors common to every seed, RMS of the seed-mean error/1-sigma per ROE "
                  f"({' '.join(c['roe'])}): {' '.join(f'{x:.2f}' for x in c['rms_seed_mean_z'])}; "
                  f"x {' '.join(f'{x:.1f}' for x in c['ratio_to_independent'])} what independent runs give")
    for k, t in s["targets"].items():
        d = t.get("by_direction") or {}
        if d.get("mean_z2_per_principal_direction"):
            print(f"{k}: mean (error/1-sigma)^2 along the covariance's principal directions, thinnest first: "
                  f"{' '.join(f'{x:.2f}' for x in d['mean_z2_per_principal_direction'])}; per ROE: "
                  f"{' '.join(f'{x:.2f}' for x in d.get('mean_z2_per_roe', []))} (1 each when consistent)")
    for fl in s["failures"]:
        print(f"failed: seed {fl['seed']}: {fl['problem']} ({os.path.join(out, fl['log'])})")
    print(f"summary: {os.path.join(out, 'campaign_summary.json')}")


if __name__ == "__main__":
    sys.exit(main())
