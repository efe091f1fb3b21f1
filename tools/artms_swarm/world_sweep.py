#!/usr/bin/python3
"""World sweep (issue 17): variants of one scenario whose world differs from the onboard model, one verdict each.

usage: world_sweep.py --out DIR [--base config/swarms/starling_pse_flight.yaml] [--cases a,b,...]
                      [--orbits 12] [--seed 7] [--settle-orbits 2] [--jobs 2] [--bin build/bin]
                      [--rerun] [--dry-run] [--list]

Each case of CASES (below) is a set of YAML edits applied to a copy of the
base scenario; everything else of the base is kept. The variant is written to
DIR/<case>.yaml (kept: a user can re-run it) and run as

    artms-swarm run DIR/<case>.yaml --seed S --orbits N --in-process --no-report --out DIR/<case>

--jobs cases at a time (output in DIR/logs/<case>.log). A run folder is reused
when its campaign_run.json (campaign.py's record: sha256 of the variant's
bytes, span, seed, mode) matches and its processes exited 0; --rerun runs
every case again (do so after rebuilding artms-swarm).

Per (case, observer, target) one row: the final |a*dlambda error| and
a*dlambda 1-sigma in % of range, the final max over the six ROE of
|error|/sigma, whether every ROE ends within 3 sigma (summary.json); the first
time after --settle-orbits that some ROE error exceeds 5 sigma
(eval/targets.csv), with the largest |error|/sigma over the ROE at the step
before and at that step (an impulsive change of the world, a burn, passes 5
sigma within one step: no measurement can come before it); the first health event of the observer naming the target
at or after that time (events.log: "suspect (health 1)", "unhealthy (",
"health check 1 failed", "health check 5"; a filter-wide "SOD unhealthy (...)"
counts for every target); the longest stretch beyond 5 sigma (orbits, whole
run, and of it while the target reported itself healthy; summary.json). The
verdict (issue 17's acceptance rule): PASS when every ROE ends within 3 sigma,
or when a health event for the target comes before its error first passes 5
sigma; FAIL in any case when the longest stretch beyond 5 sigma exceeds 1
orbit. Times are orbits of the observer (summary.json period_s) from the
scenario epoch.

Prints the table and the PASS/FAIL count; writes DIR/world_sweep.md and
DIR/world_sweep.json (the same run folders give the same bytes). --dry-run
only writes the variants and checks each with `artms-swarm validate`.
Exit status: 0 when every case ran (or validated), 1 when one did not, 2 on a
usage error or a base that does not validate.
Needs Debian's python3-yaml.
"""
import argparse
import concurrent.futures
import copy
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.realpath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
sys.path.insert(0, HERE)
from artms_tools.oem import tt_ns_from_utc  # noqa: E402
from artms_tools.runfolder import RunFolderError, read_csv, read_summary  # noqa: E402
from campaign import reuse_verdict, run_seed, say as campaign_say  # noqa: E402  (one run = one campaign seed, same record)


# ---------------------------------------------------------------- the cases

class Scale:
    """Edit value: the key's value in the base (or `default`, the schema's default, when the base leaves it out)
    times `factor`."""

    def __init__(self, factor, default):
        self.factor, self.default = factor, default

    def __repr__(self):
        return f"x{self.factor:g} (default {self.default:g})"


DELETE = "<delete>"  # edit value: remove the key (the schema's default applies)

# Edits: "path": value. A path is keys joined by '.'; `list[key=value]` selects the one item of a list whose
# `key` is `value` (in `faults` a missing item is created as {key: value}); `list[+]` appends the value.
# Schema defaults used by Scale: spacecraft drag_area_m2 0.068, cd 2.2 (config/swarms/SCHEMA.md).
ALONG_TRACK_0_05 = [0.0, 0.05, 0.0]
CASES = [
    {"name": "flight", "description": "the base scenario as shipped", "edits": {}},
    {"name": "tag_plus_0.05", "description": "SV4's frame time tags +0.05 s off (fault), no ground correction",
     "edits": {"faults[observer=SV4].time_tag_offset_s": 0.05,
               "observers[spacecraft=SV4].camera.time_tag_correction_s": DELETE}},
    {"name": "drag_area_10pct", "description": "420 km orbit (SV4 a = 6798 km); truth drag area SV2 x1.1, SV3 x0.9",
     "edits": {"spacecraft[id=SV4].qns.a_km": 6798,
               "spacecraft[id=SV2].drag_area_m2": Scale(1.1, 0.068),
               "spacecraft[id=SV3].drag_area_m2": Scale(0.9, 0.068)}},
    {"name": "drag_area_2x", "description": "420 km orbit (SV4 a = 6798 km); truth drag area SV2 x2",
     "edits": {"spacecraft[id=SV4].qns.a_km": 6798,
               "spacecraft[id=SV2].drag_area_m2": Scale(2.0, 0.068)}},
    {"name": "cd_3x", "description": "truth Cd of SV2 x3",
     "edits": {"spacecraft[id=SV2].cd": Scale(3.0, 2.2)}},
    {"name": "observer_burn", "description": "SV4 (the observer) burns 0.05 m/s along-track at 6 h, planned and "
     "uplinked, executed with a 5 % error",
     "edits": {"maneuvers[+]": {"spacecraft": "SV4", "epoch": "6h", "dv_rtn_mps": ALONG_TRACK_0_05, "planned": True,
                                "execution_sigma_fraction": 0.05}}},
    {"name": "observer_burn_unplanned", "description": "SV4 (the observer) burns 0.05 m/s along-track at 6 h, "
     "not uplinked (a thruster fault)",
     "edits": {"maneuvers[+]": {"spacecraft": "SV4", "epoch": "6h", "dv_rtn_mps": ALONG_TRACK_0_05}}},
    {"name": "osculating_table2", "description": "Table 2 ROE of SV2 and SV3 read as osculating (the base: mean)",
     "edits": {"spacecraft[id=SV2].relative.roe_type": "osculating",
               "spacecraft[id=SV3].relative.roe_type": "osculating"},
     # Only when the base reads both as mean; otherwise this case:
     "only_if": lambda base: all(_roe_type(base, s) == "mean" for s in ("SV2", "SV3")),
     "otherwise": {"name": "mean_table2", "description": "Table 2 ROE of SV2 and SV3 read as mean (the base: osculating)",
                   "edits": {"spacecraft[id=SV2].relative.roe_type": "mean",
                             "spacecraft[id=SV3].relative.roe_type": "mean"}}},
    {"name": "tag_drift_50ppm", "description": "SV4's frame time tags drift 50 ppm",
     "edits": {"faults[observer=SV4].time_tag_drift_ppm": 50}},
    {"name": "drag_area_50pct", "description": "truth drag area SV2 x1.5, SV3 x0.5",
     "edits": {"spacecraft[id=SV2].drag_area_m2": Scale(1.5, 0.068),
               "spacecraft[id=SV3].drag_area_m2": Scale(0.5, 0.068)}},
    {"name": "target_burn", "description": "SV2 (a target) burns 0.05 m/s along-track at 8 h",
     "edits": {"maneuvers[+]": {"spacecraft": "SV2", "epoch": "8h", "dv_rtn_mps": ALONG_TRACK_0_05}}},
    # The clock cases with SOD estimating the offset and drift from wide priors (a filter setting, not the world).
    {"name": "tag_plus_0.05_estimated", "description": "tag_plus_0.05 with SOD estimating the time-tag offset and "
     "drift from the schema's wide priors (1 s, 100 ppm)",
     "edits": {"faults[observer=SV4].time_tag_offset_s": 0.05,
               "observers[spacecraft=SV4].camera.time_tag_correction_s": DELETE,
               "tuning.sod.time_tag": {"estimate": "drift"}}},
    {"name": "tag_drift_50ppm_estimated", "description": "tag_drift_50ppm with SOD estimating the time-tag offset "
     "and drift from the schema's wide priors (1 s, 100 ppm)",
     "edits": {"faults[observer=SV4].time_tag_drift_ppm": 50, "tuning.sod.time_tag": {"estimate": "drift"}}},
]

HEALTH_PATTERNS = ("suspect (health 1)", "unhealthy (", "health check 1 failed", "health check 5")
ROE = ("da", "dlambda", "dex", "dey", "dix", "diy")
CREATABLE = ("faults",)


def _roe_type(base, sc_id):
    for sc in base.get("spacecraft") or []:
        if isinstance(sc, dict) and sc.get("id") == sc_id and isinstance(sc.get("relative"), dict):
            return sc["relative"].get("roe_type", "osculating")
    return None


def resolve_cases(base):
    """CASES with their conditional alternatives resolved against the base: [{name, description, edits, aliases}]."""
    out = []
    for c in CASES:
        alt = c.get("otherwise")
        chosen = c if alt is None or c["only_if"](base) else alt
        names = [c["name"]] + ([alt["name"]] if alt else [])
        out.append({"name": chosen["name"], "description": chosen["description"], "edits": chosen["edits"],
                    "aliases": names})
    return out


# ---------------------------------------------------------------- YAML in and out

def _resolvers():
    """pyyaml's implicit resolvers, but as the scenario loader reads scalars (YAML 1.2 core): timestamps stay
    strings, only true/false are booleans, 1e-3 is a number."""
    import yaml
    table = {}
    for ch, lst in yaml.resolver.Resolver.yaml_implicit_resolvers.items():
        keep = [(t, r) for t, r in lst if t not in ("tag:yaml.org,2002:timestamp", "tag:yaml.org,2002:bool",
                                                    "tag:yaml.org,2002:float")]
        if keep:
            table[ch] = keep
    extra = [("tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), "tTfF"),
             ("tag:yaml.org,2002:float",
              re.compile(r"^(?:[-+]?(?:[0-9]+\.[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?|[-+]?[0-9]+[eE][-+]?[0-9]+"
                         r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"), list("-+0123456789.")),
             ]
    for tag, rx, first in extra:
        for ch in first:
            table.setdefault(ch, []).insert(0, (tag, rx))
    return table


def _yaml_classes():
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    class Dumper(yaml.SafeDumper):
        pass

    res = _resolvers()
    Loader.yaml_implicit_resolvers = res
    Dumper.yaml_implicit_resolvers = res

    def construct_float(loader, node):
        return float(loader.construct_scalar(node))

    Loader.add_constructor("tag:yaml.org,2002:float", construct_float)

    def represent_list(dumper, data):  # short lists of numbers and strings on one line, as the shipped files
        flow = all(not isinstance(x, (dict, list)) for x in data)
        return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)

    Dumper.add_representer(list, represent_list)
    return Loader, Dumper


def load_yaml(path):
    import yaml
    loader, _ = _yaml_classes()
    with open(path) as f:
        return yaml.load(f, Loader=loader)


def dump_yaml(doc):
    import yaml
    _, dumper = _yaml_classes()
    return yaml.dump(doc, Dumper=dumper, sort_keys=False, default_flow_style=False, width=120, allow_unicode=False)


# ---------------------------------------------------------------- edits

class EditError(ValueError):
    pass


_SEG = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[(?:(\+)|([A-Za-z_][A-Za-z0-9_]*)=([^\]]+))\])?$")


def _number(v):
    """A float rounded to 12 significant digits (0.068 * 1.1 -> 0.0748); integers stay integers."""
    if isinstance(v, float) and v.is_integer() and abs(v) < 1e15:
        return v
    return float(f"{v:.12g}") if isinstance(v, float) else v


def apply_edit(doc, path, value):
    segs = path.split(".")
    node = doc
    for i, seg in enumerate(segs):
        m = _SEG.match(seg)
        if not m:
            raise EditError(f"{path}: bad path segment {seg!r}")
        key, append, sel_key, sel_val = m.groups()
        last = i == len(segs) - 1
        if not isinstance(node, dict):
            raise EditError(f"{path}: {'.'.join(segs[:i]) or 'the document'} is not a mapping")
        if append:
            if not last:
                raise EditError(f"{path}: [+] only on the last segment")
            lst = node.setdefault(key, [])
            if not isinstance(lst, list):
                raise EditError(f"{path}: {key} is not a list")
            lst.append(copy.deepcopy(value))
            return
        if sel_key is not None:
            lst = node.get(key)
            if lst is None and key in CREATABLE:
                lst = node[key] = []
            if not isinstance(lst, list):
                raise EditError(f"{path}: the base has no list {key!r}")
            hits = [x for x in lst if isinstance(x, dict) and str(x.get(sel_key)) == sel_val]
            if len(hits) > 1:
                raise EditError(f"{path}: {len(hits)} items of {key} have {sel_key} = {sel_val}")
            if not hits:
                if key not in CREATABLE:
                    raise EditError(f"{path}: no item of {key} has {sel_key} = {sel_val} in the base")
                lst.append({sel_key: sel_val})
                hits = lst[-1:]
            if last:
                raise EditError(f"{path}: a selected item needs a key after it")
            node = hits[0]
            continue
        if last:
            if value is DELETE:
                node.pop(key, None)
            elif isinstance(value, Scale):
                old = node.get(key, value.default)
                if not isinstance(old, (int, float)) or isinstance(old, bool):
                    raise EditError(f"{path}: {old!r} is not a number")
                node[key] = _number(float(old) * value.factor)
            else:
                node[key] = copy.deepcopy(value)
            return
        nxt = node.get(key)
        if nxt is None:
            nxt = node[key] = {}
        node = nxt


def make_variant(base, case):
    doc = copy.deepcopy(base)
    for path, value in case["edits"].items():
        apply_edit(doc, path, value)
    return doc


def edit_text(case):
    def show(v):
        if v is DELETE:
            return "deleted"
        return repr(v) if isinstance(v, Scale) else json.dumps(v)
    return [f"{p} = {show(v)}" for p, v in case["edits"].items()]


def run_command(yaml_name, run_name, seed, orbits, swarm="artms-swarm"):
    return [swarm, "run", yaml_name, "--seed", str(seed), "--orbits", repr(float(orbits)), "--in-process",
            "--no-report", "--out", run_name]


def variant_text(case, doc, base_path, base_sha, seed, orbits):
    lines = [f"# world_sweep.py case {case['name']}: {case['description']}",
             f"# Variant of {base_path} (sha256 {base_sha[:16]}...); edits:"]
    lines += [f"#   {e}" for e in edit_text(case)] or ["#   (none)"]
    lines += ["# Run it again (from this folder) with:",
              "#   " + " ".join(run_command(f"{case['name']}.yaml", case["name"], seed, orbits)), ""]
    return "\n".join(lines) + dump_yaml(doc)


# ---------------------------------------------------------------- one run folder -> rows

_EVENT = re.compile(r"^(\S+) \[([^\]]+)\] (\w+): (.*)$")


def _utc_to_tt(text):
    t = str(text).strip().replace(" ", "T")
    if re.fullmatch(r"\d{4}-\d{2}-\d{2}", t):
        t += "T00:00:00Z"
    return tt_ns_from_utc(t)


def health_events(run_dir, observer, target):
    """[(t_tt_ns, text)] of events.log: the observer's health events naming the target (or the whole filter)."""
    path = os.path.join(run_dir, "events.log")
    out = []
    try:
        with open(path, errors="replace") as f:
            lines = f.read().splitlines()
    except FileNotFoundError:
        return out
    name = re.compile(r"(?<![A-Za-z0-9_-])" + re.escape(target) + r"(?![A-Za-z0-9_-])")
    for line in lines:
        m = _EVENT.match(line)
        if not m or m.group(2) != f"observer-{observer}":
            continue
        msg = m.group(4)
        if not any(p in msg for p in HEALTH_PATTERNS) or re.match(r"SOD target \S+ healthy again", msg):
            continue
        if not (name.search(msg) or msg.startswith("SOD unhealthy (")):
            continue
        try:
            out.append((_utc_to_tt(m.group(1)), msg))
        except ValueError:
            continue
    return out


_SHORT = [  # events.log health texts (common/fsw navigator) -> the gist, for the table (the JSON keeps the text)
    (re.compile(r"suspect \(health 1\): its bearings do not fit its covariance \(health check 5: mean NIS ([^ ]+)"),
     r"suspect: health check 5 (mean NIS \1)"),
    (re.compile(r"suspect \(health 1\): no bearing for ([^ ]+) s while the unbound IMP track"),
     r"suspect: no bearing for \1 s, an unbound track near"),
    (re.compile(r"unhealthy \(health check 1: squared Mahalanobis distance ([^ ]+) .*?\): (re-initialised from BOD)"),
     r"health check 1 failed (d2 \1): \2"),
]


def shorten(msg, target, n=60):
    msg = re.sub(r"^SOD target " + re.escape(target) + r" ", "", msg)
    for rx, short in _SHORT:
        m = rx.search(msg)
        if m:
            return m.expand(short)
    return msg if len(msg) <= n else msg[:n - 3] + "..."


def _finite(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def case_rows(case_name, run_dir, epoch_tt, settle_orbits):
    """One dict per observer/target of a finished run folder."""
    summ = read_summary(run_dir)
    # The run's own epoch (a base scenario with epoch_window draws it from the seed); the file's for
    # run folders that predate summary.json's epoch.
    epoch_tt = int((summ.get("epoch") or {}).get("tt_ns", epoch_tt))
    table = read_csv(os.path.join(run_dir, "eval", "targets.csv"),
                     required=["t_tt_ns", "observer", "target"] + [f"err_a_{r}_m" for r in ROE]
                     + [f"sigma_a_{r}_m" for r in ROE])
    series = {}
    for r in table:
        series.setdefault((r["observer"], r["target"]), []).append(r)
    rows = []
    for obs, o in (summ.get("observers") or {}).items():
        period = o.get("period_s")
        if not _finite(period) or period <= 0:
            raise RunFolderError(f"{run_dir}/summary.json: observers.{obs}.period_s missing")
        settle_ns = epoch_tt + round(settle_orbits * period * 1e9)

        def orbits(t_ns):
            return (t_ns - epoch_tt) * 1e-9 / period

        for tgt, t in sorted((o.get("targets") or {}).items()):
            err, sig = t.get("final_error_a_roe_m"), t.get("final_sigma_a_roe_m")
            pts = sorted(series.get((obs, tgt), []), key=lambda r: r.int("t_tt_ns"))
            if not (isinstance(err, list) and isinstance(sig, list) and len(err) == len(sig) == 6) and pts:
                err = [pts[-1].float(f"err_a_{r}_m", math.nan) for r in ROE]
                sig = [pts[-1].float(f"sigma_a_{r}_m", math.nan) for r in ROE]
            z = [abs(e) / s if _finite(e) and _finite(s) and s > 0 else math.inf
                 for e, s in zip(err or [], sig or [])]
            max_z = max(z) if z else None
            within3 = bool(z) and all(v <= 3.0 for v in z)
            first5 = None
            z_before5 = z_at5 = None  # max |e|/sigma over the ROE at the step before the first 5-sigma step and at it
            for k, r in enumerate(pts):
                tn = r.int("t_tt_ns")
                if tn < settle_ns:
                    continue
                if any(_beyond(r.float(f"err_a_{q}_m", math.nan), r.float(f"sigma_a_{q}_m", math.nan), 5.0)
                       for q in ROE):
                    first5 = tn
                    z_at5 = _max_z(r)
                    z_before5 = _max_z(pts[k - 1]) if k > 0 else None
                    break
            ev = [(tn, msg) for tn, msg in health_events(run_dir, obs, tgt) if tn >= settle_ns]
            health_t, health_msg = ev[0] if ev else (None, None)
            longest = t.get("longest_beyond_5sigma_orbits")
            longest_h = t.get("longest_beyond_5sigma_reported_healthy_orbits")
            if not _finite(longest):
                longest = _longest_beyond(pts, period)
            flagged_first = health_t is not None and (first5 is None or health_t <= first5)
            if _finite(longest) and longest > 1.0:
                verdict, why = "FAIL", "beyond 5 sigma for more than 1 orbit"
            elif within3:
                verdict, why = "PASS", "every ROE ends within 3 sigma"
            elif flagged_first:
                verdict, why = "PASS", "a health event came before 5 sigma"
            else:
                verdict, why = "FAIL", ("ends beyond 3 sigma, no health event before 5 sigma" if first5 is not None
                                        else "ends beyond 3 sigma without a health event")
            rows.append({
                "case": case_name, "observer": obs, "target": tgt,
                "final_dlambda_error_pct": _num(abs(t["final_dlambda_error_pct"])
                                                if _finite(t.get("final_dlambda_error_pct")) else None),
                "final_dlambda_sigma_pct": _num(t.get("final_dlambda_sigma_pct")),
                "final_max_error_over_sigma": _num(max_z),
                "final_error_over_sigma": {q: _num(v) for q, v in zip(ROE, z)},
                "final_within_3sigma": within3,
                "first_beyond_5sigma_orbits": _num(orbits(first5)) if first5 is not None else None,
                "max_error_over_sigma_step_before_5sigma": _num(z_before5),
                "max_error_over_sigma_at_5sigma": _num(z_at5),
                "first_health_event_orbits": _num(orbits(health_t)) if health_t is not None else None,
                "first_health_event": health_msg,
                "health_events_after_settle": len(ev),
                "longest_beyond_5sigma_orbits": _num(longest),
                "longest_beyond_5sigma_reported_healthy_orbits": _num(longest_h),
                "frac_beyond_5sigma": _num(t.get("frac_beyond_5sigma")),
                "convergence_orbits": _num(t.get("convergence_orbits")),
                "nees_mean": _num(t.get("nees_mean")),
                "verdict": verdict, "why": why,
            })
    return rows


def _beyond(e, s, n):
    return _finite(e) and _finite(s) and abs(e) > n * s


def _max_z(r):
    """max over the six ROE of |error| / 1-sigma on one eval/targets.csv row (None when none is finite)."""
    z = [abs(r.float(f"err_a_{q}_m", math.nan)) / r.float(f"sigma_a_{q}_m", math.nan) for q in ROE
         if _finite(r.float(f"err_a_{q}_m", math.nan)) and r.float(f"sigma_a_{q}_m", math.nan) > 0]
    return max(z) if z else None


def _longest_beyond(pts, period):
    """summary.json's longest_beyond_5sigma_orbits when it is missing: the longest run of steps with some ROE beyond
    5 sigma, times the mean step, in orbits."""
    if len(pts) < 2:
        return None
    t = [r.int("t_tt_ns") for r in pts]
    step_s = (t[-1] - t[0]) * 1e-9 / (len(t) - 1)
    run = longest = 0
    for r in pts:
        out = any(_beyond(r.float(f"err_a_{q}_m", math.nan), r.float(f"sigma_a_{q}_m", math.nan), 5.0) for q in ROE)
        run = run + 1 if out else 0
        longest = max(longest, run)
    return longest * step_s / period


def _num(v):
    """A finite number rounded to 6 significant digits (stable JSON), else None."""
    return float(f"{v:.6g}") if _finite(v) else None


# ---------------------------------------------------------------- tables

COLUMNS = [("case", "case"), ("pair", "obs->tgt"), ("err", "dl err %"), ("sig", "dl 1sig %"),
           ("maxz", "max |e|/sig"), ("in3", "all <=3sig"), ("first5", "first >5sig [orb]"),
           ("jump", "max |e|/sig: step before -> at it"),
           ("health", "first health event [orb]: text"), ("longest", "longest >5sig [orb] (healthy)"),
           ("verdict", "verdict")]


def _f(v, spec):
    return spec.format(v) if _finite(v) else "-"


def cells(row):
    if row.get("problem"):
        return {"case": row["case"], "pair": "-", "err": "-", "sig": "-", "maxz": "-", "in3": "-", "first5": "-", "jump": "-",
                "health": "run failed: " + row["problem"][:60], "longest": "-", "verdict": "NO RUN"}
    h = "-"
    if row["first_health_event_orbits"] is not None:
        h = f"{row['first_health_event_orbits']:.2f}: {shorten(row['first_health_event'], row['target'])}"
    return {"case": row["case"], "pair": f"{row['observer']}->{row['target']}",
            "err": _f(row["final_dlambda_error_pct"], "{:.3f}"), "sig": _f(row["final_dlambda_sigma_pct"], "{:.3f}"),
            "maxz": _f(row["final_max_error_over_sigma"], "{:.2f}"), "in3": "yes" if row["final_within_3sigma"] else "no",
            "first5": _f(row["first_beyond_5sigma_orbits"], "{:.2f}"),
            "jump": (f"{_f(row['max_error_over_sigma_step_before_5sigma'], '{:.1f}')} -> "
                     f"{_f(row['max_error_over_sigma_at_5sigma'], '{:.1f}')}"
                     if row["first_beyond_5sigma_orbits"] is not None else "-"),
            "health": h,
            "longest": f"{_f(row['longest_beyond_5sigma_orbits'], '{:.2f}')} "
                       f"({_f(row['longest_beyond_5sigma_reported_healthy_orbits'], '{:.2f}')})",
            "verdict": row["verdict"]}


def text_table(rows):
    cs = [cells(r) for r in rows]
    w = {k: max([len(h)] + [len(c[k]) for c in cs]) for k, h in COLUMNS}
    lines = ["  ".join(h.ljust(w[k]) for k, h in COLUMNS).rstrip()]
    lines += ["  ".join(c[k].ljust(w[k]) for k, _ in COLUMNS).rstrip() for c in cs]
    return "\n".join(lines)


def md_table(rows):
    cs = [cells(r) for r in rows]
    esc = lambda s: s.replace("|", "\\|")  # noqa: E731
    lines = ["| " + " | ".join(esc(h) for _, h in COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(esc(c[k]) for k, _ in COLUMNS) + " |" for c in cs]
    return "\n".join(lines)


def counts(rows):
    c = {"PASS": 0, "FAIL": 0, "NO RUN": 0}
    for r in rows:
        c[r["verdict"]] = c.get(r["verdict"], 0) + 1
    return c


RULE = ("PASS if every ROE ends within 3 sigma, or a health event for the target (at or after the settle time) "
        "comes before its error first passes 5 sigma; FAIL in any case if the longest stretch beyond 5 sigma "
        "exceeds 1 orbit")


# ---------------------------------------------------------------- main

def say(msg):
    campaign_say(msg, "world_sweep")


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="world_sweep.py", description=__doc__.split("\n")[0])
    ap.add_argument("--base", default=os.path.join(ROOT, "config", "swarms", "starling_pse_flight.yaml"),
                    help="base scenario (default config/swarms/starling_pse_flight.yaml)")
    ap.add_argument("--out", help="sweep folder: <case>.yaml, <case>/ (run folders), logs/, world_sweep.{md,json}")
    ap.add_argument("--cases", help="comma-separated case names (default: all; --list shows them)")
    ap.add_argument("--orbits", type=float, default=12.0, help="simulated orbits per run (default 12)")
    ap.add_argument("--seed", type=int, default=7, help="seed of every run (default 7)")
    ap.add_argument("--settle-orbits", type=float, default=2.0,
                    help="5-sigma crossings and health events before this are not counted (default 2: the a-priori)")
    ap.add_argument("--jobs", type=int, default=2, help="cases run at a time (default 2)")
    ap.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"), help="folder of artms-swarm (default build/bin)")
    ap.add_argument("--rerun", action="store_true", help="run every case again, even when its run folder is reusable")
    ap.add_argument("--dry-run", action="store_true", help="only write the variants and validate them")
    ap.add_argument("--list", action="store_true", help="list the cases (against --base) and exit")
    a = ap.parse_args(argv)
    if not a.list and not a.out:
        ap.error("--out is required")
    if a.jobs < 1:
        ap.error("--jobs must be at least 1")
    if not (a.orbits > 0 and math.isfinite(a.orbits)):
        ap.error("--orbits must be positive")
    if not (a.settle_orbits >= 0 and math.isfinite(a.settle_orbits)):
        ap.error("--settle-orbits must be >= 0")
    return a


def validate(swarm, path):
    r = subprocess.run([swarm, "validate", path], capture_output=True, text=True)
    return r.returncode == 0, (r.stdout + r.stderr).strip()


def main(argv=None):
    args = parse_args(argv)
    base_abs = os.path.abspath(args.base)
    # Shown (variant headers, tables, JSON) relative to the source tree when inside it: the same on every checkout.
    base_path = os.path.relpath(base_abs, ROOT) if base_abs.startswith(ROOT + os.sep) else base_abs
    try:
        with open(base_abs, "rb") as f:
            base_bytes = f.read()
        base = load_yaml(base_abs)
    except (OSError, ValueError) as e:
        say(f"cannot read the base scenario: {e}")
        return 2
    if not isinstance(base, dict):
        say(f"{base_path}: not a YAML mapping")
        return 2
    base_sha = hashlib.sha256(base_bytes).hexdigest()
    cases = resolve_cases(base)
    if args.list:
        for c in cases:
            print(f"{c['name']:<18} {c['description']}")
            for e in edit_text(c):
                print(f"{'':<18}   {e}")
        return 0
    if args.cases:
        want = [n.strip() for n in args.cases.split(",") if n.strip()]
        unknown = [n for n in want if not any(n in c["aliases"] for c in cases)]
        if unknown:
            say(f"unknown case(s) {', '.join(unknown)}; cases: {', '.join(c['name'] for c in cases)}")
            return 2
        cases = [c for c in cases if any(n in c["aliases"] for n in want)]

    swarm = os.path.join(os.path.abspath(args.bin), "artms-swarm")
    if not os.access(swarm, os.X_OK):
        say(f"no artms-swarm in {os.path.abspath(args.bin)} (build first, or give --bin)")
        return 2
    ok, text = validate(swarm, base_abs)
    if not ok:
        say(f"the base scenario does not validate:\n{text}")
        return 2
    epoch = base.get("epoch")
    try:
        epoch_tt = _utc_to_tt(epoch)
    except (TypeError, ValueError) as e:
        say(f"{base_path}: epoch {epoch!r}: {e}")
        return 2

    out = os.path.abspath(args.out)
    os.makedirs(os.path.join(out, "logs"), exist_ok=True)
    bad = []
    for c in cases:
        try:
            doc = make_variant(base, c)
        except EditError as e:
            say(f"case {c['name']}: {e}")
            return 2
        c["yaml"] = os.path.join(out, f"{c['name']}.yaml")
        text = variant_text(c, doc, base_path, base_sha, args.seed, args.orbits)
        with open(c["yaml"] + ".tmp", "w") as f:
            f.write(text)
        os.replace(c["yaml"] + ".tmp", c["yaml"])
        c["sha256"] = hashlib.sha256(text.encode()).hexdigest()
        ok, msg = validate(swarm, c["yaml"])
        say(f"case {c['name']}: {c['name']}.yaml " + ("valid" if ok else f"does NOT validate:\n{msg}"))
        if not ok:
            bad.append(c["name"])
    if args.dry_run:
        print(f"{len(cases) - len(bad)} of {len(cases)} variants valid in {out}" + (f"; invalid: {', '.join(bad)}"
                                                                                    if bad else ""))
        return 1 if bad else 0

    span = {"orbits": float(args.orbits)}
    jobs = []
    for c in cases:
        d = os.path.join(out, c["name"])
        c["run_dir"] = d
        c["problem"] = "the variant does not validate" if c["name"] in bad else None
        if c["problem"]:
            continue
        record = {"scenario_sha256": c["sha256"], "span": span, "seed": args.seed, "mode": "in-process",
                  "seed_plots": False}
        if os.path.exists(d):
            reusable, why = (False, "--rerun") if args.rerun else reuse_verdict(d, record)
            if reusable:
                say(f"case {c['name']}: run folder reused (same variant, span, seed)")
                continue
            say(f"case {c['name']}: run folder stale ({why}): running it again")
            shutil.rmtree(d)
        cmd = run_command(c["yaml"], d, args.seed, args.orbits, swarm)
        jobs.append({"seed": args.seed, "cmd": cmd, "dir": d, "log": os.path.join(out, "logs", f"{c['name']}.log"),
                     "record": record, "case": c})

    def one(job):
        say(f"case {job['case']['name']} started")
        try:
            res = run_seed(job)
        except Exception as e:  # a bug: record it, go on
            res = {"ok": False, "problem": f"{type(e).__name__}: {e}", "wall_s": 0.0, "tail": []}
        if res["ok"]:
            say(f"case {job['case']['name']} finished in {res['wall_s']:.1f} s")
        else:
            job["case"]["problem"] = res["problem"]
            tail = "\n".join("    " + s for s in res["tail"])
            say(f"case {job['case']['name']} FAILED: {res['problem']} (log {job['log']})" + (f"\n{tail}" if tail else ""))
        return res

    if jobs:
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as ex:
            try:
                list(ex.map(one, jobs))
            except KeyboardInterrupt:
                say("interrupted")
                ex.shutdown(wait=False, cancel_futures=True)
                return 130

    rows = []
    for c in cases:
        if not c["problem"]:
            try:
                rows += case_rows(c["name"], c["run_dir"], epoch_tt, args.settle_orbits)
                continue
            except (RunFolderError, OSError, KeyError, ValueError) as e:
                c["problem"] = f"cannot read the run folder: {e}"
        rows.append({"case": c["name"], "problem": c["problem"], "verdict": "NO RUN"})
    n = counts(rows)
    tally = f"PASS {n['PASS']}, FAIL {n['FAIL']}" + (f", NO RUN {n['NO RUN']}" if n["NO RUN"] else "")
    head = (f"world sweep of {base_path}: {len(cases)} cases, {args.orbits:g} orbits, seed {args.seed}, "
            f"settle {args.settle_orbits:g} orbits")

    rel = lambda p: os.path.relpath(p, out)  # noqa: E731
    summary = {"base": base_path, "base_sha256": base_sha, "orbits": float(args.orbits), "seed": args.seed,
               "settle_orbits": float(args.settle_orbits), "rule": RULE, "health_patterns": list(HEALTH_PATTERNS),
               "cases": [{"name": c["name"], "description": c["description"], "edits": edit_text(c),
                          "yaml": rel(c["yaml"]), "yaml_sha256": c["sha256"], "run_dir": rel(c["run_dir"]),
                          "command": " ".join(run_command(rel(c["yaml"]), rel(c["run_dir"]), args.seed, args.orbits)),
                          "problem": c["problem"]} for c in cases],
               "rows": rows, "counts": n}
    with open(os.path.join(out, "world_sweep.json"), "w") as f:
        json.dump(summary, f, indent=1)
        f.write("\n")
    md = [f"# World sweep (issue 17)", "", head + ".", "", f"Verdict: {RULE}.", "",
          "Times in orbits of the observer from the epoch; 'dl' is a*dlambda in % of range; 'longest' is the "
          "whole run's longest stretch with some ROE beyond 5 sigma (in brackets: of it while the target reported "
          "itself healthy).", "", md_table(rows), "", f"**{tally}**", "", "## Cases", ""]
    for c in summary["cases"]:
        md.append(f"* `{c['name']}`: {c['description']} (`{c['yaml']}`; "
                  + ("; ".join(f"`{e}`" for e in c["edits"]) or "no edits") + ")")
    md += ["", "Re-run one case from this folder: `artms-swarm run <case>.yaml --seed "
           f"{args.seed} --orbits {float(args.orbits)!r} --in-process --no-report --out <case>`.", ""]
    with open(os.path.join(out, "world_sweep.md"), "w") as f:
        f.write("\n".join(md))
    print(head)
    print(text_table(rows))
    print(tally)
    print(f"tables: {os.path.join(out, 'world_sweep.md')}, {os.path.join(out, 'world_sweep.json')}")
    return 1 if n["NO RUN"] else 0


if __name__ == "__main__":
    sys.exit(main())
