#!/usr/bin/python3
"""Unit test of tools/artms_swarm/world_sweep.py without artms-swarm: the YAML edits and reader, the case list,
the health events of events.log and the verdict of issue 17 on made-up run folders.

usage: world_sweep_test.py   (run by tests/integration/world_sweep.sh)
"""
import json
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..", "tools", "artms_swarm"))
import world_sweep as ws  # noqa: E402
from artms_tools.oem import tt_ns_from_utc  # noqa: E402  (world_sweep put tools/python on sys.path)

PERIOD = 6000.0  # s: one orbit = 100 steps of 60 s
EPOCH = "2024-05-08T00:00:00Z"
ROE = ws.ROE


class EditTest(unittest.TestCase):
    BASE = {"name": "x", "epoch": EPOCH, "duration": "19h",
            "spacecraft": [{"id": "SV4", "qns": {"a_km": 6943}},
                           {"id": "SV2", "relative": {"chief": "SV4", "roe_m": [1, 2, 3, 4, 5, 6], "roe_type": "mean"},
                            "cd": 2.5},
                           {"id": "SV3", "relative": {"chief": "SV4", "roe_m": [1, 2, 3, 4, 5, 6], "roe_type": "mean"}}],
            "observers": [{"spacecraft": "SV4", "camera": {"time_tag_correction_s": 0.4}}],
            "faults": [{"observer": "SV4", "time_tag_offset_s": -0.4}]}

    def test_every_case_edits_only_its_keys(self):
        cases = ws.resolve_cases(self.BASE)
        self.assertEqual(len(cases), len(ws.CASES))
        self.assertEqual(len(cases), 13)
        by = {c["name"]: ws.make_variant(self.BASE, c) for c in cases}
        self.assertEqual(by["flight"], self.BASE)
        self.assertEqual(by["cd_3x"]["spacecraft"][1]["cd"], 7.5)  # x3 of the base's truth value
        v = by["drag_area_10pct"]
        self.assertEqual(v["spacecraft"][0]["qns"]["a_km"], 6798)
        self.assertEqual(v["spacecraft"][1]["drag_area_m2"], 0.0748)  # x1.1 of the default 0.068
        self.assertEqual(v["spacecraft"][2]["drag_area_m2"], 0.0612)
        self.assertNotIn("onboard", v["spacecraft"][1])
        v = by["tag_plus_0.05"]
        self.assertEqual(v["faults"], [{"observer": "SV4", "time_tag_offset_s": 0.05}])
        self.assertNotIn("time_tag_correction_s", v["observers"][0]["camera"])
        self.assertEqual(by["tag_drift_50ppm"]["faults"][0], {"observer": "SV4", "time_tag_offset_s": -0.4,
                                                              "time_tag_drift_ppm": 50})
        self.assertEqual(by["target_burn"]["maneuvers"], [{"spacecraft": "SV2", "epoch": "8h",
                                                            "dv_rtn_mps": [0.0, 0.05, 0.0]}])
        self.assertEqual(by["osculating_table2"]["spacecraft"][2]["relative"]["roe_type"], "osculating")
        self.assertEqual(self.BASE["spacecraft"][1]["cd"], 2.5)  # the base itself is never changed

    def test_a_base_read_as_osculating_gets_the_mean_case(self):
        base = json.loads(json.dumps(self.BASE))
        for sc in base["spacecraft"][1:]:
            del sc["relative"]["roe_type"]
        names = [c["name"] for c in ws.resolve_cases(base)]
        self.assertIn("mean_table2", names)
        self.assertNotIn("osculating_table2", names)

    def test_a_missing_spacecraft_is_an_error_a_missing_fault_is_created(self):
        with self.assertRaises(ws.EditError):
            ws.apply_edit(json.loads(json.dumps(self.BASE)), "spacecraft[id=SV9].cd", 1.0)
        doc = {"spacecraft": []}
        ws.apply_edit(doc, "faults[observer=SV4].time_tag_drift_ppm", 50)
        self.assertEqual(doc["faults"], [{"observer": "SV4", "time_tag_drift_ppm": 50}])

    def test_yaml_keeps_the_scenario_scalars(self):
        with tempfile.TemporaryDirectory() as d:
            p = os.path.join(d, "a.yaml")
            with open(p, "w") as f:
                f.write("epoch: 2024-05-08T00:00:00Z\nx: 1e-3\nn: 7\nb: true\ns: 6h\nl: [1, -2.5]\n")
            doc = ws.load_yaml(p)
            self.assertEqual(doc, {"epoch": EPOCH, "x": 0.001, "n": 7, "b": True, "s": "6h", "l": [1, -2.5]})
            text = ws.dump_yaml(doc)
            self.assertIn("epoch: 2024-05-08T00:00:00Z\n", text)
            self.assertIn("l: [1, -2.5]\n", text)
            with open(p, "w") as f:
                f.write(text)
            self.assertEqual(ws.load_yaml(p), doc)


def make_run(d, errs, health_lines, longest=0.0):
    """A run folder of one observer SV4 and target SV2: eval/targets.csv with err/sigma per step (sigma 1 m,
    the error `errs[k]` in dlambda at step k of 60 s), summary.json and events.log."""
    os.makedirs(os.path.join(d, "eval"))
    t0 = tt_ns_from_utc(EPOCH)
    cols = (["t_utc", "t_tt_ns", "observer", "target", "range_m"] + [f"err_a_{r}_m" for r in ROE]
            + [f"sigma_a_{r}_m" for r in ROE] + ["local_measurements", "remote_measurements", "health", "nees"])
    with open(os.path.join(d, "eval", "targets.csv"), "w") as f:
        f.write(",".join(cols) + "\n")
        for k, e in enumerate(errs):
            f.write(f"x,{t0 + k * 60 * 10**9},SV4,SV2,1000," + ",".join(["0", str(e)] + ["0"] * 4) + ","
                    + ",".join(["1"] * 6) + ",0,0,0,1\n")
    err = [0.0, errs[-1], 0, 0, 0, 0]
    summ = {"observers": {"SV4": {"period_s": PERIOD, "targets": {"SV2": {
        "final_dlambda_error_pct": 0.1 * errs[-1], "final_dlambda_sigma_pct": 0.1,
        "final_error_a_roe_m": err, "final_sigma_a_roe_m": [1.0] * 6,
        "longest_beyond_5sigma_orbits": longest, "longest_beyond_5sigma_reported_healthy_orbits": longest}}}}}
    with open(os.path.join(d, "summary.json"), "w") as f:
        json.dump(summ, f)
    with open(os.path.join(d, "events.log"), "w") as f:
        f.write("".join(line + "\n" for line in health_lines))


def at(step):
    h, m = divmod(step, 60)
    return f"2024-05-08T{h:02d}:{m:02d}:00.000Z"


class VerdictTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()

    def tearDown(self):
        self.tmp.cleanup()

    def row(self, errs, lines, longest=0.0, settle=2.0):
        d = os.path.join(self.tmp.name, f"run{len(os.listdir(self.tmp.name))}")
        make_run(d, errs, lines, longest)
        rows = ws.case_rows("c", d, tt_ns_from_utc(EPOCH), settle)
        self.assertEqual(len(rows), 1)
        return rows[0]

    def test_ends_within_3_sigma(self):
        r = self.row([0.5] * 300, [])
        self.assertEqual((r["verdict"], r["final_within_3sigma"], r["first_beyond_5sigma_orbits"]), ("PASS", True, None))
        self.assertEqual((r["max_error_over_sigma_at_5sigma"], ws.cells(r)["jump"]), (None, "-"))

    def test_flagged_before_5_sigma_passes_flagged_after_fails(self):
        errs = [0.5] * 250 + [6.0] * 50  # beyond 5 sigma from step 250 = 2.5 orbits
        early = f"{at(240)} [observer-SV4] warning: SOD target SV2 suspect (health 1): its bearings do not fit"
        late = f"{at(260)} [observer-SV4] warning: SOD target SV2 unhealthy (large residuals: x): re-initialised"
        r = self.row(errs, [early])
        self.assertEqual((r["verdict"], r["first_beyond_5sigma_orbits"], r["first_health_event_orbits"]),
                         ("PASS", 2.5, 2.4))
        # The jump past 5 sigma: the largest |error|/sigma at the step before and at the first step beyond.
        self.assertEqual((r["max_error_over_sigma_step_before_5sigma"], r["max_error_over_sigma_at_5sigma"]),
                         (0.5, 6.0))
        self.assertEqual(ws.cells(r)["jump"], "0.5 -> 6.0")
        self.assertEqual(self.row(errs, [late])["verdict"], "FAIL")

    def test_longer_than_an_orbit_beyond_5_sigma_fails_in_any_case(self):
        r = self.row([0.5] * 300, [], longest=1.2)
        self.assertEqual((r["verdict"], r["final_within_3sigma"]), ("FAIL", True))

    def test_which_events_count(self):
        errs = [0.5] * 250 + [4.0] * 50  # ends beyond 3 sigma, never beyond 5
        before_settle = f"{at(100)} [observer-SV4] warning: SOD target SV2 suspect (health 1): x"
        other_target = f"{at(210)} [observer-SV4] warning: SOD target SV22 suspect (health 1): x"
        other_observer = f"{at(211)} [observer-SV3] warning: SOD target SV2 suspect (health 1): x"
        recovery = f"{at(212)} [observer-SV4] info: SOD target SV2 healthy again: health check 5 fits"
        passed = f"{at(213)} [observer-SV4] info: BOD attempt 3 ...; health check 1 passed for target SV2"
        r = self.row(errs, [before_settle, other_target, other_observer, recovery, passed])
        self.assertEqual((r["verdict"], r["first_health_event_orbits"]), ("FAIL", None))
        whole = f"{at(220)} [observer-SV4] warning: SOD unhealthy (no measurement update: x): re-initialising"
        r = self.row(errs, [before_settle, whole])
        self.assertEqual((r["verdict"], r["first_health_event_orbits"]), ("PASS", 2.2))
        self.assertEqual(self.row(errs, [before_settle], settle=0.5)["first_health_event_orbits"], 1.0)


if __name__ == "__main__":
    unittest.main(argv=sys.argv[:1], verbosity=1)
