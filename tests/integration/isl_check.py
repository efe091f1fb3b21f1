#!/usr/bin/env python3
"""Checks of the crosslink accounting of one run folder (issue 8), shared by
the swarm_isl_* integration tests. Prints per link sent/delivered/dropped.

usage: isl_check.py RUN_DIR [--outage START_S END_S] [--loss P]
"""
import math, os, sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..", "tools", "python"))
from artms_tools.runfolder import failed_processes, read_csv, read_summary  # noqa: E402

run = sys.argv[1]
args = sys.argv[2:]
outage = None
loss_p = None
while args:
    a = args.pop(0)
    if a == "--outage":
        outage = (float(args.pop(0)), float(args.pop(0)))
    elif a == "--loss":
        loss_p = float(args.pop(0))

s = read_summary(run)
bad = failed_processes(s)
assert not bad, f"processes with non-zero exit: {bad}"
isl = s["isl"]
rows = read_csv(f"{run}/isl.csv")
assert rows, "isl.csv is empty"
t0 = min(int(r["t_sent_tt_ns"]) for r in rows)  # first broadcast = epoch (step 0)
links = sorted(isl["per_link"])
assert len(links) >= 2, links

# summary.json against an independent count of isl.csv, and the identity.
for key in links:
    L = isl["per_link"][key]
    frm, to = key.split("->")
    mine = [r for r in rows if r["sender"] == frm and r["receiver"] == to]
    dropped = sum(L["dropped"].values())
    print(f"{key}: sent {L['sent']} delivered {L['delivered']} dropped {L['dropped']}")
    assert L["sent"] > 0, key
    assert L["sent"] == L["delivered"] + dropped, (key, L)
    assert L["sent"] == len(mine), (key, L["sent"], len(mine))
    assert L["delivered"] == sum(r["status"] == "delivered" for r in mine), key
    for reason, n in L["dropped"].items():
        assert n == sum(r["status"] == "dropped" and r["reason"] == reason for r in mine), (key, reason)
    # every broadcast of the sender appears exactly once on this link
    seqs = sorted(int(r["sequence"]) for r in mine)
    assert seqs == list(range(len(seqs))), (key, "sequence numbers not 0..n-1 exactly once")
tot = {"sent": 0, "delivered": 0}
for key in links:
    tot["sent"] += isl["per_link"][key]["sent"]
    tot["delivered"] += isl["per_link"][key]["delivered"]
assert isl["sent"] == tot["sent"] and isl["delivered"] == tot["delivered"], (isl["sent"], tot)
assert isl["sent"] == isl["delivered"] + sum(isl["dropped"].values())
print(f"total: sent {isl['sent']} delivered {isl['delivered']} dropped {isl['dropped']}")

# Receivers: what the observer counted (last telemetry row) is what the
# emulator delivered before that row's step (a relay is consumed one step
# after the emulator wrote it).
for key in links:
    frm, to = key.split("->")
nav_received = {}
for obs in sorted({k.split("->")[1] for k in links}):
    nav = read_csv(f"{run}/nav/{obs}.csv")
    last = nav[-1]
    t_last = int(last["t_tt_ns"])
    expect = sum(1 for r in rows if r["receiver"] == obs and r["status"] == "delivered" and int(r["t_tt_ns"]) < t_last)
    assert int(last["isl_received"]) == expect, (obs, last["isl_received"], expect)
    assert int(last["isl_rejected"]) == 0, (obs, last["isl_rejected"])
    assert int(last["isl_sent"]) > 0, obs
    print(f"{obs}: isl_sent {last['isl_sent']} isl_received {last['isl_received']} (= delivered before its last step)")
    if outage:
        # It kept navigating through the outage: one telemetry row per step.
        steps = sorted(int(r["t_tt_ns"]) for r in nav)
        gaps = {b - a for a, b in zip(steps, steps[1:])}
        assert len(gaps) == 1, (obs, "telemetry gaps", gaps)

if outage:
    a, b = outage
    lk = read_csv(f"{run}/links.csv")
    for key in links:
        frm, to = key.split("->")
        L = isl["per_link"][key]
        mine = [r for r in rows if r["sender"] == frm and r["receiver"] == to]
        inside = [r for r in mine if a <= (int(r["t_tt_ns"]) - t0) * 1e-9 < b]
        assert L["dropped"]["outage"] > 0, key
        assert L["dropped"]["outage"] == len(inside), (key, L["dropped"]["outage"], len(inside))
        assert all(r["reason"] == "outage" for r in inside), key
        after = [r for r in mine if (int(r["t_tt_ns"]) - t0) * 1e-9 >= b and r["status"] == "delivered"]
        assert after, (key, "no delivery after the outage")
        before = [r for r in mine if (int(r["t_tt_ns"]) - t0) * 1e-9 < a and r["status"] == "delivered"]
        assert before, (key, "no delivery before the outage")
        states = [(round((int(r["t_tt_ns"]) - t0) * 1e-9), r["up"], r["reason"]) for r in lk
                  if r["from"] == frm and r["to"] == to]
        print(f"{key}: links.csv {states}; {len(inside)} broadcasts relayed inside the window")
        assert states == [(0, "1", "start"), (round(a), "0", "outage"), (round(b), "1", "restored")], (key, states)

if loss_p is not None:
    n = isl["sent"] - sum(v for k, v in isl["dropped"].items() if k != "loss")
    k = isl["dropped"]["loss"]
    sigma = math.sqrt(n * loss_p * (1 - loss_p))
    print(f"loss: {k} of {n} relays on up links (expected {loss_p * n:.1f} +- {sigma:.1f})")
    assert abs(k - loss_p * n) <= 3 * sigma, (k, loss_p * n, sigma)
    assert k > 0
print("isl check: ok")
