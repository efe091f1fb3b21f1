#!/usr/bin/python3
"""artms-report: plots and a paper comparison for one artms-swarm run folder.

usage: artms-report RUN_DIR [--out DIR]   (DIR defaults to RUN_DIR/plots)

Reads RUN_DIR/eval/targets.csv, RUN_DIR/eval/observers.csv,
RUN_DIR/summary.json and RUN_DIR/bod/ (any of them may be missing or partial)
and writes
  roe_<observer>_<target>.png  ROE errors and +-1 sigma, measurement epochs
  observer_<observer>.png      absolute position / velocity error and 1 sigma
  bod_curves_<observer>.png    BOD residual versus a*dlambda, one line per attempt
  bod_range_<observer>.png     BOD range and its error against truth at each attempt
  summary.png, summary.md      final figures against the StarFOX flight results
Exit status: 0 when the summary was written, 1 when there was nothing to
summarise, 2 when RUN_DIR is missing or unreadable. Uses only Debian's
python3-numpy and python3-matplotlib (Agg backend).
"""
import argparse
import datetime
import json
import math
import os
import sys


def _artms_tools_dir():
    """tools/python: beside this script in the source tree; for the copy in <build>/bin, an
    ARTMS_PYTHON_DIR override, <build>/python or the source tree recorded in <build>/CMakeCache.txt."""
    here = os.path.dirname(os.path.realpath(__file__))
    dirs = [os.environ.get("ARTMS_PYTHON_DIR", ""), os.path.join(here, "..", "python"),
            os.path.join(here, "..", "share", "artms", "python")]
    cache = os.path.join(here, "..", "CMakeCache.txt")
    if os.path.isfile(cache):
        with open(cache) as f:
            dirs += [os.path.join(line.split("=", 1)[1].strip(), "tools", "python") for line in f
                     if line.startswith("CMAKE_HOME_DIRECTORY:INTERNAL=")]
    return next((d for d in dirs if d and os.path.isfile(os.path.join(d, "artms_tools", "__init__.py"))), None)


_TOOLS = _artms_tools_dir()
if _TOOLS is None:
    sys.exit("artms-report: cannot find the artms_tools package (tools/python); set ARTMS_PYTHON_DIR to that folder")
sys.path.insert(0, os.path.abspath(_TOOLS))
from artms_tools.codes import BodVerdict, NavHealth  # noqa: E402
from artms_tools.oem import read_oem  # noqa: E402
from artms_tools.runfolder import RunFolderError, read_csv as read_run_csv  # noqa: E402

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.transforms as mtransforms  # noqa: E402
import numpy as np  # noqa: E402

DPI = 150
DEFAULT_PERIOD_S = 5700.0
ROE = ["da", "dlambda", "dex", "dey", "dix", "diy"]
ROE_LABEL = {"da": r"$a\delta a$", "dlambda": r"$a\delta\lambda$", "dex": r"$a\delta e_x$",
             "dey": r"$a\delta e_y$", "dix": r"$a\delta i_x$", "diy": r"$a\delta i_y$"}
HEALTH_COLOUR = {NavHealth.REINITIALISING: ("#f2d98c", NavHealth.REINITIALISING.label),
                 NavHealth.NO_SOLUTION: ("#f4a6a6", NavHealth.NO_SOLUTION.label)}

# StarFOX flight results (starfox-paper.tex, "Relative Navigation" sections and
# tab:result). Single observer: SV4 on 05/16/24; multi-observer: SV4 on 02/05/24.
PAPER = {
    "single": {"dlambda_sigma_pct": {"SV2": 1.3, "SV3": 2.6}, "other_sigma_pct": 0.02,
               "dlambda_error_pct": 0.5, "convergence_orbits": 2.0,
               "label": "single observer (SV4, 05/16/24)"},
    "multi": {"dlambda_sigma_pct": {}, "dlambda_sigma_default": 0.6, "other_sigma_pct": 0.01,
              "dlambda_error_pct": 0.5, "convergence_orbits": 1.0,
              "label": "multi-observer (SV4, 02/05/24)"},
}
# The paper: "errors do remain within 3 sigma bounds"; it gives no number, this is ours.
FRAC3_THRESHOLD = 0.95


def warn(msg):
    print(f"artms-report: {msg}", file=sys.stderr)


def fnum(v):
    """float or NaN for missing, null, empty or unparsable values."""
    if v is None:
        return math.nan
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def finite(v):
    return v is not None and isinstance(v, (int, float)) and math.isfinite(v)


def parse_time_s(row):
    """Seconds (TT) of a CSV row: t_tt_ns if usable, else t_utc (ISO 8601)."""
    t = row.get("t_tt_ns")
    if t not in (None, ""):
        try:
            return int(t) * 1e-9
        except ValueError:
            v = fnum(t)
            if math.isfinite(v):
                return v * 1e-9
    u = row.get("t_utc")
    if u:
        try:
            return datetime.datetime.fromisoformat(u.strip().replace("Z", "+00:00")).timestamp()
        except ValueError:
            pass
    return math.nan


def read_csv(path, what):
    """List of dict rows, or None (with a message) when the file is missing or unreadable."""
    if not os.path.isfile(path):
        print(f"missing: {path} ({what})")
        return None
    try:
        rows = read_run_csv(path)
    except (OSError, UnicodeDecodeError) as e:
        print(f"unreadable: {path}: {e} ({what})")
        return None
    except RunFolderError as e:  # a malformed row: the whole file is refused, never a row dropped
        print(f"unreadable: {e} ({what})")
        return None
    if not rows:
        print(f"empty: {path} ({what})")
        return None
    return rows


def read_summary(path):
    if not os.path.isfile(path):
        print(f"missing: {path} (summary uses eval/targets.csv only, periods default to {DEFAULT_PERIOD_S:.0f} s)")
        return {}
    try:
        with open(path) as f:
            s = json.load(f)
    except (OSError, ValueError) as e:
        print(f"unreadable: {path}: {e}")
        return {}
    return s if isinstance(s, dict) else {}


def dget(d, *keys):
    """Nested dict lookup returning None for anything absent or not a dict on the way."""
    for k in keys:
        if not isinstance(d, dict):
            return None
        d = d.get(k)
    return d


def period_s(summary, obs):
    p = fnum(dget(summary, "observers", obs, "period_s"))
    return p if math.isfinite(p) and p > 0 else DEFAULT_PERIOD_S


def columns(rows, names):
    return {n: np.array([fnum(r.get(n)) for r in rows]) for n in names}


def runs(mask):
    """(start, end) index pairs of consecutive True values."""
    out, start = [], None
    for i, m in enumerate(mask):
        if m and start is None:
            start = i
        elif not m and start is not None:
            out.append((start, i - 1))
            start = None
    if start is not None:
        out.append((start, len(mask) - 1))
    return out


def shade_health(ax, x, health):
    for code, (colour, _) in HEALTH_COLOUR.items():
        for a, b in runs(health == code):
            right = x[b + 1] if b + 1 < len(x) else x[b]
            ax.axvspan(x[a], max(right, x[a] + 1e-3), color=colour, alpha=0.6, lw=0, zorder=0)


def robust_ylim(err, sig):
    """Symmetric limit from the last half of the run (x3), so the converged part is visible."""
    n = len(err)
    tail_e, tail_s = np.abs(err[n // 2:]), sig[n // 2:]
    vals = np.concatenate([tail_e[np.isfinite(tail_e)], tail_s[np.isfinite(tail_s)]])
    if vals.size == 0:
        allv = np.concatenate([np.abs(err[np.isfinite(err)]), sig[np.isfinite(sig)]])
        if allv.size == 0:
            return 1.0
        vals = allv
    lim = 3.0 * float(np.max(vals))
    return lim if lim > 0 else 1.0


def measurement_epochs(counter):
    """Indices where a cumulative counter increases from the previous valid row."""
    idx, last = [], math.nan
    for i, c in enumerate(counter):
        if not math.isfinite(c):
            continue
        if math.isfinite(last) and c > last:
            idx.append(i)
        last = c
    return np.array(idx, dtype=int)


def pct(v, rng):
    return 100.0 * v / rng if finite(v) and finite(rng) and rng > 0 else None


def fmt(v, spec="{:.2f}", none="n/a"):
    return spec.format(v) if finite(v) else none


class Pair:
    """Everything known about one observer/target pair."""

    def __init__(self, obs, tgt):
        self.obs, self.tgt = obs, tgt
        self.rows = []
        self.final_range = None
        self.err_pct = None
        self.sig_pct = None
        self.other_sig_pct = None
        self.conv_orbits = None
        self.frac3 = None  # dict component -> fraction
        self.local = None
        self.remote = None
        self.from_csv = set()  # fields filled from targets.csv


def last_finite(a):
    ok = np.isfinite(a)
    return float(a[ok][-1]) if ok.any() else None


def build_pairs(trows, summary):
    pairs = {}
    for r in trows or []:
        key = (r.get("observer") or "?", r.get("target") or "?")
        pairs.setdefault(key, Pair(*key)).rows.append(r)
    for obs, od in (dget(summary, "observers") or {}).items():
        for tgt in (dget(od, "targets") or {}):
            pairs.setdefault((obs, tgt), Pair(obs, tgt))
    for (obs, tgt), p in pairs.items():
        js = dget(summary, "observers", obs, "targets", tgt) or {}
        p.final_range = fnum(js.get("final_range_m"))
        p.err_pct = fnum(js.get("final_dlambda_error_pct"))
        p.sig_pct = fnum(js.get("final_dlambda_sigma_pct"))
        p.conv_orbits = fnum(js.get("convergence_orbits"))
        p.local = fnum(js.get("local_measurements"))
        p.remote = fnum(js.get("remote_measurements"))
        f3 = js.get("frac_within_3sigma")
        p.frac3 = {k: fnum(f3.get(k)) for k in ROE} if isinstance(f3, dict) else {}
        p.frac3 = {k: v for k, v in p.frac3.items() if math.isfinite(v)}
        if p.rows:
            fill_from_csv(p)
        finalise(p)
    return pairs


def fill_from_csv(p):
    """Fills what summary.json lacks from the pair's last targets.csv values."""
    c = columns(p.rows, ["range_m", "local_measurements", "remote_measurements", "health"]
                + [f"err_a_{k}_m" for k in ROE] + [f"sigma_a_{k}_m" for k in ROE])

    def fill(attr, value):
        if not finite(getattr(p, attr)) and value is not None:
            setattr(p, attr, value)
            p.from_csv.add(attr)

    fill("final_range", last_finite(c["range_m"]))
    R = p.final_range
    fill("err_pct", pct(last_finite(c["err_a_dlambda_m"]), R))
    fill("sig_pct", pct(last_finite(c["sigma_a_dlambda_m"]), R))
    fill("local", last_finite(c["local_measurements"]))
    fill("remote", last_finite(c["remote_measurements"]))
    others = [pct(last_finite(c[f"sigma_a_{k}_m"]), R) for k in ROE if k != "dlambda"]
    others = [v for v in others if v is not None]
    p.other_sig_pct = max(others) if others else None
    if not p.frac3:
        healthy = ~(c["health"] > 0)  # healthy or health unknown
        for k in ROE:
            e, s = c[f"err_a_{k}_m"], c[f"sigma_a_{k}_m"]
            m = healthy & np.isfinite(e) & np.isfinite(s)
            if m.any():
                p.frac3[k] = float(np.mean(np.abs(e[m]) <= 3.0 * s[m]))
        if p.frac3:
            p.from_csv.add("frac3")


def finalise(p):
    for attr in ("final_range", "err_pct", "sig_pct", "conv_orbits", "local", "remote"):
        if not finite(getattr(p, attr)):
            setattr(p, attr, None)


def paper_ref(p):
    """('single'|'multi', reference dict, dlambda 1-sigma reference in % of range)."""
    mode = "multi" if finite(p.remote) and p.remote > 0 else "single"
    ref = PAPER[mode]
    if mode == "multi":
        return mode, ref, ref["dlambda_sigma_default"]
    if p.tgt in ref["dlambda_sigma_pct"]:
        return mode, ref, ref["dlambda_sigma_pct"][p.tgt]
    # Other targets: the paper's SV2 was at ~50 km, SV3 at ~130 km.
    near = finite(p.final_range) and p.final_range < 100e3
    return mode, ref, ref["dlambda_sigma_pct"]["SV2" if near else "SV3"]


# ---------------------------------------------------------------- plots

def plot_roe(p, t0, period, out_dir):
    rows = p.rows
    c = columns(rows, ["local_measurements", "remote_measurements", "health"]
                + [f"err_a_{k}_m" for k in ROE] + [f"sigma_a_{k}_m" for k in ROE])
    t = np.array([parse_time_s(r) for r in rows])
    order = np.argsort(np.where(np.isfinite(t), t, np.inf), kind="stable")
    t = t[order]
    c = {k: v[order] for k, v in c.items()}
    x = (t - t0) / period
    health = c["health"]

    fig, axes = plt.subplots(6, 1, figsize=(8.5, 11), sharex=True)
    clipped = []
    for ax, k in zip(axes, ROE):
        e, s = c[f"err_a_{k}_m"], np.abs(c[f"sigma_a_{k}_m"])
        shade_health(ax, x, health)
        ax.fill_between(x, -s, s, color="#9ecae1", alpha=0.55, lw=0, label=r"$\pm1\sigma$")
        ax.plot(x, s, color="#3182bd", lw=0.8, ls="--")
        ax.plot(x, -s, color="#3182bd", lw=0.8, ls="--")
        ax.plot(x, e, color="black", lw=1.0, label="error")
        ax.axhline(0.0, color="grey", lw=0.5)
        lim = robust_ylim(e, s)
        ax.set_ylim(-lim, lim)
        big = np.nanmax(np.abs(np.concatenate([e, s]))) if np.isfinite(np.concatenate([e, s])).any() else 0
        if big > lim:
            clipped.append(k)
            ax.text(0.995, 0.96, f"clipped (max |.| {big:.3g} m)", transform=ax.transAxes,
                    ha="right", va="top", fontsize=7, color="dimgrey")
        ax.set_ylabel(ROE_LABEL[k] + " [m]")
        ax.grid(True, lw=0.3, alpha=0.6)
        if k == "dlambda":
            tr = mtransforms.blended_transform_factory(ax.transData, ax.transAxes)
            li = measurement_epochs(c["local_measurements"])
            ri = measurement_epochs(c["remote_measurements"])
            if li.size:
                ax.plot(x[li], np.full(li.size, 0.05), "|", color="black", ms=6, mew=0.8,
                        transform=tr, label=f"local meas. ({li.size} epochs)")
            if ri.size:
                ax.plot(x[ri], np.full(ri.size, 0.13), "|", color="tab:orange", ms=6, mew=0.8,
                        transform=tr, label=f"remote meas. ({ri.size} epochs)")
    handles, labels = axes[1].get_legend_handles_labels()
    for code, (colour, name) in HEALTH_COLOUR.items():
        if (health == code).any():
            handles.append(plt.Rectangle((0, 0), 1, 1, color=colour, alpha=0.6))
            labels.append(name)
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.955), ncol=len(labels),
               fontsize=8, frameon=False, handlelength=1.5, columnspacing=1.2)
    axes[-1].set_xlabel(f"orbits since first row (period {period:.0f} s)")
    if np.isfinite(x).any():
        axes[-1].set_xlim(np.nanmin(x), np.nanmax(x))
    rng = f"{p.final_range / 1e3:.1f} km" if finite(p.final_range) else "n/a"
    title = (f"{p.obs} \u2192 {p.tgt}   final range {rng}\n"
             f"final $a\\delta\\lambda$ error {fmt(p.err_pct)} %, 1$\\sigma$ {fmt(p.sig_pct)} % of range")
    fig.suptitle(title, fontsize=11, y=0.985)
    fig.tight_layout(rect=(0, 0, 1, 0.955))
    path = os.path.join(out_dir, f"roe_{safe(p.obs)}_{safe(p.tgt)}.png")
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def plot_observer(obs, rows, t0, period, out_dir):
    c = columns(rows, ["pos_err_m", "vel_err_mps", "sigma_pos_m", "sigma_vel_mps"])
    t = np.array([parse_time_s(r) for r in rows])
    order = np.argsort(np.where(np.isfinite(t), t, np.inf), kind="stable")
    t = t[order]
    c = {k: v[order] for k, v in c.items()}
    labels = [f"{r.get('mode', '') or '?'}/{r.get('source', '') or '?'}" for r in (rows[i] for i in order)]
    x = (t - t0) / period
    fig, axes = plt.subplots(2, 1, figsize=(8.5, 6), sharex=True)
    for ax, (err, sig, unit, name) in zip(axes, [("pos_err_m", "sigma_pos_m", "m", "position"),
                                                ("vel_err_mps", "sigma_vel_mps", "m/s", "velocity")]):
        e, s = np.abs(c[err]), np.abs(c[sig])
        e = np.where(e > 0, e, np.nan)
        s = np.where(s > 0, s, np.nan)
        ax.plot(x, e, color="black", lw=1.0, label=f"{name} error (3-D RSS)")
        ax.plot(x, s, color="#3182bd", lw=1.0, ls="--", label=r"1$\sigma$ (3-D RSS)")
        if np.isfinite(e).any() or np.isfinite(s).any():
            ax.set_yscale("log")
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(True, which="both", lw=0.3, alpha=0.6)
        ax.legend(fontsize=8, loc="upper right")
    # Mode/source changes as dotted lines with the new label.
    tr = mtransforms.blended_transform_factory(axes[0].transData, axes[0].transAxes)
    for i, lab in enumerate(labels):
        if (i == 0 or lab != labels[i - 1]) and math.isfinite(x[i]):
            for ax in axes:
                ax.axvline(x[i], color="dimgrey", lw=0.6, ls=":")
            axes[0].text(x[i], 1.01, lab, transform=tr, fontsize=7, rotation=0, ha="left", va="bottom",
                         color="dimgrey")
    axes[-1].set_xlabel(f"orbits since first row (period {period:.0f} s)")
    if np.isfinite(x).any():
        axes[-1].set_xlim(np.nanmin(x), np.nanmax(x))
    last = last_finite(c["pos_err_m"])
    lsig = last_finite(c["sigma_pos_m"])
    fig.suptitle(f"{obs} absolute orbit: final position error {fmt(last, '{:.1f}')} m, "
                 f"1$\\sigma$ {fmt(lsig, '{:.1f}')} m", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    path = os.path.join(out_dir, f"observer_{safe(obs)}.png")
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def save_figure(fig, out_dir, name, rect=None):
    """tight_layout (leaving `rect` for a suptitle), write out_dir/name at DPI, close; the path."""
    fig.tight_layout(**({"rect": rect} if rect else {}))
    path = os.path.join(out_dir, name)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


OE_NAMES = [("da", "a"), ("du", "u"), ("dex", "e_x"), ("dey", "e_y"), ("di", "i"), ("draan", r"\Omega")]


def plot_absolute(obs, rows, t0, period, out_dir):
    """The paper's mode-4 figure: the observer's orbit element errors times a with their 1-sigma, and its
    RTN position errors with 1-sigma (eval/observers.csv; columns written since issue 18)."""
    names = [f"err_a_{n}_m" for n, _ in OE_NAMES] + [f"sigma_a_{n}_m" for n, _ in OE_NAMES]
    rtn = ["err_r_m", "err_t_m", "err_n_m", "sigma_r_m", "sigma_t_m", "sigma_n_m"]
    if not rows or any(n not in rows[0] for n in names + rtn):
        return []
    c = columns(rows, names + rtn)
    t = np.array([parse_time_s(r) for r in rows])
    order = np.argsort(np.where(np.isfinite(t), t, np.inf), kind="stable")
    x = (t[order] - t0) / 3600.0
    c = {k: v[order] for k, v in c.items()}
    written = []
    fig, axes = plt.subplots(3, 2, figsize=(10, 7.5), sharex=True)
    for ax, (n, label) in zip(axes.T.flatten(), OE_NAMES):
        e, sg = c[f"err_a_{n}_m"], c[f"sigma_a_{n}_m"]
        ax.plot(x, e, color="black", lw=0.9, label="error")
        ax.plot(x, sg, color="#3182bd", lw=0.9, ls="--", label=r"$\pm 1\sigma$")
        ax.plot(x, -sg, color="#3182bd", lw=0.9, ls="--")
        ax.set_ylabel(rf"$a\,\delta {label}$ [m]")
        lim = np.nanmax(np.concatenate([np.abs(e), np.abs(sg), [1.0]]))
        ax.set_ylim(-1.1 * lim, 1.1 * lim)
        ax.grid(True, lw=0.3, alpha=0.6)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    for ax in axes[-1]:
        ax.set_xlabel("hours since first row")
    fig.suptitle(f"{obs}: absolute orbit element errors (times a) and 1$\\sigma$", fontsize=11)
    written.append(save_figure(fig, out_dir, f"absolute_oe_{safe(obs)}.png", rect=(0, 0, 1, 0.96)))
    fig, axes = plt.subplots(3, 1, figsize=(8.5, 7), sharex=True)
    for ax, axis in zip(axes, "RTN"):
        e, sg = c[f"err_{axis.lower()}_m"], c[f"sigma_{axis.lower()}_m"]
        ax.plot(x, e, color="black", lw=0.9, label=f"{axis} error")
        ax.plot(x, 3 * sg, color="#de2d26", lw=0.8, ls=":", label=r"$\pm 3\sigma$")
        ax.plot(x, -3 * sg, color="#de2d26", lw=0.8, ls=":")
        ax.set_ylabel(f"{axis} [m]")
        ax.grid(True, lw=0.3, alpha=0.6)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1].set_xlabel("hours since first row")
    pe = np.sqrt(c["err_r_m"] ** 2 + c["err_t_m"] ** 2 + c["err_n_m"] ** 2)
    fig.suptitle(f"{obs}: absolute position error in its RTN frame: {fmt(first_finite(pe), '{:.0f}')} m at the "
                 f"start, {fmt(last_finite(pe), '{:.0f}')} m at the end", fontsize=11)
    written.append(save_figure(fig, out_dir, f"absolute_rtn_{safe(obs)}.png", rect=(0, 0, 1, 0.96)))
    return written


def first_finite(a):
    a = np.asarray(a, dtype=float)
    ok = np.isfinite(a)
    return float(a[ok][0]) if ok.any() else None


def plot_isl_received(run_dir, t0, out_dir):
    """The paper's ISL figure: per receiving observer, the bearings it received over each link (isl.csv,
    delivered broadcasts), cumulative over time."""
    rows = read_csv(os.path.join(run_dir, "isl.csv"), "no ISL plot")
    if not rows:
        return []
    links = {}
    for r in rows:
        if r.get("status") != "delivered":
            continue
        try:
            n = int(r.get("measurements") or 0)
        except ValueError:
            continue
        t = parse_time_s(r)
        if n > 0 and math.isfinite(t):
            links.setdefault(r.get("receiver") or "?", {}).setdefault(r.get("sender") or "?", []).append((t, n))
    written = []
    for receiver in sorted(links):
        fig, ax = plt.subplots(figsize=(8.5, 3.8))
        for sender in sorted(links[receiver]):
            pts = sorted(links[receiver][sender])
            x = (np.array([p[0] for p in pts]) - t0) / 3600.0
            y = np.cumsum([p[1] for p in pts])
            ax.step(x, y, where="post", lw=1.0, label=f"{sender} -> {receiver}: {int(y[-1])} bearings")
        ax.set_xlabel("hours since first row")
        ax.set_ylabel("bearings received (cumulative)")
        ax.grid(True, lw=0.3, alpha=0.6)
        ax.legend(fontsize=8, loc="upper left")
        ax.set_title(f"ISL bearings received by {receiver}, per link", fontsize=11)
        written.append(save_figure(fig, out_dir, f"isl_received_{safe(receiver)}.png"))
    return written


# ---------------------------------------------------------------- BOD

def bod_observers(run_dir):
    """Observers with a bod/<observer>_curves.csv."""
    d = os.path.join(run_dir, "bod")
    tail = "_curves.csv"
    return sorted(f[:-len(tail)] for f in os.listdir(d) if f.endswith(tail)) if os.path.isdir(d) else []


def usable(row):
    return row.get("verdict") == str(int(BodVerdict.USABLE))


def plot_bod_curves(obs, attempts, curves, out_dir, truth=None, period=None):
    """The paper's residual versus a*dlambda: one line per attempt (dotted where a sample did not
    converge), the chosen sample (the converged one with the smallest residual) marked o, a usable
    attempt's refined estimate x, and the truth (the orbit mean of the true range at t_est, what
    BOD's mean a*dlambda estimates) marked v on the curve when truth is known."""
    info = {r.get("attempt"): r for r in attempts or []}
    by_attempt = {}
    for r in curves:
        by_attempt.setdefault(r.get("attempt"), []).append(r)
    keys = sorted(by_attempt, key=fnum)
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, max(len(keys), 1)))
    fig, ax = plt.subplots(figsize=(8.5, 5.5))
    marked_truth = False
    for colour, n in zip(colours, keys):
        c = columns(by_attempt[n], ["a_dlambda_m", "residual_rms_arcsec", "converged"])
        x, y, conv = c["a_dlambda_m"] / 1e3, c["residual_rms_arcsec"], c["converged"] == 1
        a = info.get(n, {})
        ax.plot(x, y, color=colour, lw=0.6, ls=":")
        ax.plot(x, np.where(conv, y, np.nan), color=colour, lw=1.2,
                label=f"{n}: {(a.get('t_utc') or '?')[:16]} {a.get('verdict_name') or '?'}")
        ok = conv & np.isfinite(y)
        if ok.any():
            i = int(np.argmin(np.where(ok, y, np.inf)))
            ax.plot(x[i], y[i], "o", color=colour, ms=6, mec="black", mew=0.6)
        if a and usable(a):
            ax.plot(fnum(a.get("a_dlambda_m")) / 1e3, fnum(a.get("residual_rms_arcsec")), "x", color="black", ms=7)
        ser = truth.series(obs, a["target"]) if truth is not None and period and a and a.get("target") else None
        if ser is not None:
            mean = orbit_mean(ser[0], ser[1], fnum(a.get("t_tt_ns")), period)
            if mean is not None and ok.any():
                xt = math.copysign(mean, np.nanmedian(x)) / 1e3
                order = np.argsort(x)
                yt = float(np.interp(xt, x[order], np.where(ok, y, np.nan)[order]))
                ax.plot(xt, yt, "v", color=colour, ms=8, mec="black", mew=0.6)
                marked_truth = True
    if np.isfinite(columns(curves, ["residual_rms_arcsec"])["residual_rms_arcsec"]).any():
        ax.set_yscale("log")
    ax.set_xlabel(r"$a\delta\lambda$ [km]")
    ax.set_ylabel("residual RMS [arcsec]")
    ax.grid(True, which="both", lw=0.3, alpha=0.6)
    if len(keys) <= 12:
        ax.legend(fontsize=7, title="attempt: t_est (UTC) verdict", title_fontsize=7, loc="upper right")
    ax.set_title(f"{obs} BOD residual curves ({len(keys)} attempts; o chosen sample, x estimate"
                 + (", v truth" if marked_truth else "") + ")", fontsize=11)
    fig.tight_layout()
    path = os.path.join(out_dir, f"bod_curves_{safe(obs)}.png")
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


class TrueRange:
    """True observer-target distance at any time: from truth.oem (interpolated between epochs), else
    from eval/targets.csv's range_m (the true range at each navigation step)."""

    def __init__(self, run_dir, trows):
        self.source, self.segments, self.trows = None, {}, trows or []
        path = os.path.join(run_dir, "truth.oem")
        if os.path.isfile(path):
            try:
                self.segments = {s.object_name: s for s in read_oem(path).segments}
                self.source = "truth.oem"
            except (OSError, RunFolderError) as e:
                print(f"unreadable: {e} (BOD range errors from eval/targets.csv)")
        if not self.segments and self.trows:
            self.source = "eval/targets.csv"

    def series(self, obs, tgt):
        """(t_tt_ns, range_m) arrays, or None."""
        if obs in self.segments and tgt in self.segments:
            o, t = self.segments[obs], self.segments[tgt]
            if o.t_tt_ns == t.t_tt_ns:
                return (np.array(o.t_tt_ns, dtype=float),
                        np.linalg.norm(np.array(t.r_m) - np.array(o.r_m), axis=1))
        rows = [r for r in self.trows if r.get("observer") == obs and r.get("target") == tgt]
        if rows:
            c = columns(rows, ["t_tt_ns", "range_m"])
            ok = np.isfinite(c["t_tt_ns"]) & np.isfinite(c["range_m"])
            if ok.any():
                order = np.argsort(c["t_tt_ns"][ok], kind="stable")
                return c["t_tt_ns"][ok][order], c["range_m"][ok][order]
        return None


def orbit_mean(t_ns, rng, t, period):
    """Secular part of the true range at t: a least-squares fit of c0 + c1 dt + a sin(n dt) + b cos(n dt)
    (n = 2 pi / period) to the samples within one period of t, evaluated at t (c0): the orbit-averaged
    separation that BOD's mean a*dlambda estimates. None with less than 3/4 of an orbit of samples."""
    dt = (t_ns - t) * 1e-9
    w = np.abs(dt) <= period
    if w.sum() < 8 or np.ptp(dt[w]) < 0.75 * period:
        return None
    n = 2.0 * math.pi / period
    A = np.column_stack([np.ones(w.sum()), dt[w], np.sin(n * dt[w]), np.cos(n * dt[w])])
    return float(np.linalg.lstsq(A, rng[w], rcond=None)[0][0])


def plot_bod_range(obs, attempts, truth, t0, period, out_dir):
    """BOD range (a*|dlambda| of the mean ROE) +-1 sigma at each attempt with the true range (top) and its
    error (bottom) against the true range's orbit mean (black; what BOD estimates) and against the
    instantaneous true distance at t_est (grey x); usable attempts filled, the others open. None when no
    attempt has a known truth."""
    rows = [r for r in attempts if fnum(r.get("range_m")) > 0 and r.get("target")]
    series = {tgt: truth.series(obs, tgt) for tgt in sorted({r["target"] for r in rows})}
    rows = [r for r in rows if series.get(r["target"]) is not None
            and series[r["target"]][0][0] <= fnum(r.get("t_tt_ns")) <= series[r["target"]][0][-1]]
    if not rows:
        return None
    fig, axes = plt.subplots(2, 1, figsize=(8.5, 6.5), sharex=True)
    x_of = lambda t_ns: (t_ns * 1e-9 - t0) / period  # noqa: E731
    for tgt, (t_ns, rng) in ((k, v) for k, v in series.items() if v is not None):
        axes[0].plot(x_of(t_ns), rng / 1e3, color="grey", lw=0.8, label=f"true range to {tgt} ({truth.source})")
    means = 0
    for r in rows:
        t_ns, rng = series[r["target"]]
        t = fnum(r.get("t_tt_ns"))
        x, est, sig = x_of(t), fnum(r.get("range_m")), fnum(r.get("sigma_range_m"))
        face = "black" if usable(r) else "none"
        axes[0].errorbar(x, est / 1e3, yerr=sig / 1e3, fmt="o", color="black", mfc=face, ms=4, capsize=3, lw=0.8)
        axes[1].plot(x, est - float(np.interp(t, t_ns, rng)), "x", color="grey", ms=6)
        mean = orbit_mean(t_ns, rng, t, period)
        if mean is not None:
            means += 1
            axes[0].plot(x, mean / 1e3, "_", color="tab:red", ms=14, mew=1.5)
            axes[1].errorbar(x, est - mean, yerr=sig, fmt="o", color="black", mfc=face, ms=4, capsize=3, lw=0.8)
    handles, labels = axes[0].get_legend_handles_labels()
    handles.append(plt.Line2D([], [], ls="none", marker="_", color="tab:red", ms=10, mew=1.5))
    labels.append("its orbit mean at t_est")
    axes[0].legend(handles, labels, fontsize=8, loc="best")
    axes[0].set_ylabel("range [km]")
    axes[1].axhline(0.0, color="grey", lw=0.5)
    axes[1].set_ylabel("BOD range error [m]")
    axes[1].legend([plt.Line2D([], [], ls="none", marker="o", color="black"),
                    plt.Line2D([], [], ls="none", marker="x", color="grey")],
                   [r"against the orbit mean, $\pm1\sigma$" + ("" if means == len(rows) else f" ({means})"),
                    "against the true range at t_est"], fontsize=8, loc="best")
    axes[1].set_xlabel(f"orbits since first row (period {period:.0f} s)")
    for ax in axes:
        ax.grid(True, lw=0.3, alpha=0.6)
    n_ok = sum(usable(r) for r in rows)
    fig.suptitle(f"{obs} BOD range at each attempt ({len(rows)}, {n_ok} usable: filled)", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    path = os.path.join(out_dir, f"bod_range_{safe(obs)}.png")
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def plot_bod(run_dir, trows, summary, t0, out_dir):
    written = []
    truth = None
    for obs in bod_observers(run_dir):
        curves = read_csv(os.path.join(run_dir, "bod", f"{obs}_curves.csv"), "no BOD residual curves")
        attempts = read_csv(os.path.join(run_dir, "bod", f"{obs}.csv"), "no BOD range plot") or []
        if curves:
            try:
                truth = truth or TrueRange(run_dir, trows)
                written.append(plot_bod_curves(obs, attempts, curves, out_dir, truth, period_s(summary, obs)))
            except Exception as e:
                warn(f"BOD curves plot {obs} failed: {type(e).__name__}: {e}")
        if not attempts:
            continue
        try:
            truth = truth or TrueRange(run_dir, trows)
            t_first = [fnum(r.get("t_tt_ns")) * 1e-9 for r in attempts]
            start = t0 if t0 is not None else min(t for t in t_first if math.isfinite(t))
            path = plot_bod_range(obs, attempts, truth, start, period_s(summary, obs), out_dir)
            if path:
                written.append(path)
            else:
                print(f"no truth for the BOD attempts of {obs} (truth.oem, eval/targets.csv): no BOD range plot")
        except Exception as e:
            warn(f"BOD range plot {obs} failed: {type(e).__name__}: {e}")
    return written


def safe(name):
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in str(name)) or "_"


# ---------------------------------------------------------------- summary

def verdict(ok):
    return "n/a" if ok is None else ("PASS" if ok else "FAIL")


def summary_rows(pairs):
    """Header and rows (cells, verdicts of the JUDGED columns) of the comparison table."""
    header = ["observer", "target", "mode", "range [km]",
              "aδλ 1σ [% range]", "paper 1σ", "aδλ error [%]", "paper error",
              "other ROE 1σ [%]", "paper other", "conv. [orbits]", "paper conv.",
              "min frac 3σ", "ref. frac 3σ", "meas. local/remote"]
    table = []
    for (obs, tgt) in sorted(pairs):
        p = pairs[(obs, tgt)]
        mode, ref, sig_ref = paper_ref(p)

        def star(field):
            return "*" if field in p.from_csv else ""

        fr_comp = min(p.frac3, key=p.frac3.get) if p.frac3 else None
        fr_min = p.frac3[fr_comp] if fr_comp else None
        verdicts = [None if p.sig_pct is None else p.sig_pct <= sig_ref,
                    None if p.err_pct is None else abs(p.err_pct) <= ref["dlambda_error_pct"],
                    None if p.other_sig_pct is None else p.other_sig_pct < ref["other_sigma_pct"],
                    None if p.conv_orbits is None else p.conv_orbits <= ref["convergence_orbits"],
                    None if fr_min is None else fr_min >= FRAC3_THRESHOLD]
        v = [verdict(x) for x in verdicts]
        rng_km = p.final_range / 1e3 if p.final_range is not None else None
        cells = [obs, tgt, mode, fmt(rng_km, "{:.1f}") + star("final_range"),
                 fmt(p.sig_pct, "{:.3f}") + star("sig_pct"), f"{sig_ref:g} % {v[0]}",
                 fmt(p.err_pct, "{:+.3f}") + star("err_pct"), f"|e|≤{ref['dlambda_error_pct']:g} % {v[1]}",
                 fmt(p.other_sig_pct, "{:.4f}"), f"<{ref['other_sigma_pct']:g} % {v[2]}",
                 fmt(p.conv_orbits, "{:.1f}"), f"≤{ref['convergence_orbits']:g} {v[3]}",
                 fmt(fr_min, "{:.3f}") + (f" ({fr_comp})" if fr_comp else "") + star("frac3"),
                 f"≥{FRAC3_THRESHOLD:g} {v[4]}",
                 f"{fmt(p.local, '{:.0f}', '-')}{star('local')}/{fmt(p.remote, '{:.0f}', '-')}{star('remote')}"]
        table.append((cells, verdicts))
    return header, table


JUDGED = [5, 7, 9, 11, 13]  # table columns carrying a verdict, in the order of the verdicts


def run_info(summary, run_dir):
    name = summary.get("scenario") if isinstance(summary.get("scenario"), str) else None
    dur = fnum(summary.get("duration_s"))
    orb = fnum(summary.get("orbits"))
    bits = [f"scenario: {name or os.path.basename(os.path.abspath(run_dir))}"]
    if math.isfinite(dur):
        bits.append(f"duration {dur / 3600:.2f} h")
    if math.isfinite(orb):
        bits.append(f"{orb:.1f} orbits")
    return ", ".join(bits)


NOTES = [
    "Paper values: StarFOX flight results (starfox-paper.tex). Single observer, SV4 05/16/24: "
    "aδλ 1σ 1.3 % (SV2, ~50 km) and 2.6 % (SV3, ~130 km) of range, other ROE 1σ < 0.02 %; "
    "multi-observer, SV4 02/05/24: aδλ 1σ 0.6 % (SV2 and SV3), other ROE 1σ < 0.01 %. "
    "tab:result: error 0.5 % of range (in flight, both), convergence 2 orbits (single) / 1 orbit (multi).",
    "Mode is 'multi' when the pair used remote measurements. Targets other than SV2/SV3 in single-observer mode "
    "are compared with SV2's 1.3 % below 100 km range and SV3's 2.6 % above.",
    f"min frac 3σ: smallest fraction of steps with |error| ≤ 3σ over the six ROE; the paper states errors stay "
    f"within 3σ but gives no number, the {FRAC3_THRESHOLD:g} threshold is ours.",
    "* computed from eval/targets.csv (absent from summary.json). n/a: not available.",
]


def write_summary(pairs, summary, run_dir, out_dir):
    header, table = summary_rows(pairs)
    info = run_info(summary, run_dir)
    md = os.path.join(out_dir, "summary.md")
    with open(md, "w") as f:
        f.write(f"# ARTMS run report\n\n{info}\n\n")
        if table:
            f.write("| " + " | ".join(header) + " |\n")
            f.write("|" + "---|" * len(header) + "\n")
            for cells, _ in table:
                f.write("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |\n")
        else:
            f.write("No observer/target pairs found in eval/targets.csv or summary.json.\n")
        f.write("\n" + "\n".join(f"- {n}" for n in NOTES) + "\n")

    png = os.path.join(out_dir, "summary.png")
    n = max(len(table), 1)
    top_in, row_in, notes_in = 0.55, 0.34, 0.95  # title band, table row, notes band (inches)
    height = top_in + row_in * (n + 1) + notes_in
    fig = plt.figure(figsize=(17, height))
    fig.text(0.01, 1 - 0.12 / height, "ARTMS run vs StarFOX flight results \u2014 " + info, fontsize=12,
             va="top", weight="bold")
    if table:
        ax = fig.add_axes((0.01, notes_in / height, 0.98, row_in * (n + 1) / height))
        ax.axis("off")
        tab = ax.table(cellText=[cells for cells, _ in table], colLabels=header, bbox=(0, 0, 1, 1),
                       cellLoc="center")
        tab.auto_set_font_size(False)
        tab.set_fontsize(8.5)
        for r, (_, verdicts) in enumerate(table, start=1):
            for col, v in zip(JUDGED, verdicts):
                colour = "#e8e8e8" if v is None else ("#b7e4b0" if v else "#f4b6b6")
                tab[r, col].set_facecolor(colour)
        for col in range(len(header)):
            tab[0, col].set_facecolor("#d9d9d9")
            tab[0, col].set_text_props(weight="bold")
        tab.auto_set_column_width(list(range(len(header))))
    else:
        fig.text(0.01, 0.5, "No observer/target pairs found in eval/targets.csv or summary.json.", fontsize=11)
    fig.text(0.01, 0.08 / height, "\n".join(NOTES), fontsize=7.5, va="bottom", wrap=True)
    fig.savefig(png, dpi=DPI)
    plt.close(fig)
    return [png, md]


# ---------------------------------------------------------------- main

def main(argv=None):
    ap = argparse.ArgumentParser(prog="artms-report", description=__doc__.split("\n")[0])
    ap.add_argument("run_dir", metavar="RUN_DIR")
    ap.add_argument("--out", help="output folder (default RUN_DIR/plots)")
    args = ap.parse_args(argv)
    run_dir = args.run_dir
    if not os.path.isdir(run_dir) or not os.access(run_dir, os.R_OK | os.X_OK):
        warn(f"run folder {run_dir!r} does not exist or is not readable")
        return 2
    out_dir = args.out or os.path.join(run_dir, "plots")
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as e:
        warn(f"cannot create {out_dir}: {e}")
        return 1

    summary = read_summary(os.path.join(run_dir, "summary.json"))
    trows = read_csv(os.path.join(run_dir, "eval", "targets.csv"), "no ROE plots")
    orows = read_csv(os.path.join(run_dir, "eval", "observers.csv"), "no observer plots")

    times = [parse_time_s(r) for r in (trows or []) + (orows or [])]
    times = [t for t in times if math.isfinite(t)]
    t0 = min(times) if times else 0.0
    if (trows or orows) and not times:
        print("no usable t_tt_ns or t_utc times: skipping plots")

    written = []
    pairs = build_pairs(trows, summary)
    if times:
        for key in sorted(pairs):
            p = pairs[key]
            if not p.rows:
                continue
            try:
                written.append(plot_roe(p, t0, period_s(summary, p.obs), out_dir))
            except Exception as e:  # one bad pair must not stop the others
                warn(f"roe plot {p.obs}/{p.tgt} failed: {type(e).__name__}: {e}")
        by_obs = {}
        for r in orows or []:
            by_obs.setdefault(r.get("observer") or "?", []).append(r)
        for obs in sorted(by_obs):
            try:
                written.append(plot_observer(obs, by_obs[obs], t0, period_s(summary, obs), out_dir))
                written += plot_absolute(obs, by_obs[obs], t0, period_s(summary, obs), out_dir)
            except Exception as e:
                warn(f"observer plot {obs} failed: {type(e).__name__}: {e}")
        try:
            written += plot_isl_received(run_dir, t0, out_dir)
        except Exception as e:
            warn(f"ISL plot failed: {type(e).__name__}: {e}")
    written += plot_bod(run_dir, trows, summary, t0 if times else None, out_dir)

    if not pairs:
        print("nothing to summarise: no observer/target pairs in eval/targets.csv or summary.json")
    try:
        written += write_summary(pairs, summary, run_dir, out_dir)
        ok = bool(pairs)
    except Exception as e:
        warn(f"summary failed: {type(e).__name__}: {e}")
        ok = False
    print("written:")
    for w in written:
        print(f"  {w}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
