#!/usr/bin/python3
"""Unit test of tools/python/artms_tools (run-folder CSV reader, codes, OEM reader, UTC -> TT).

usage: python_tools_test.py [RUN_DIR]
With RUN_DIR (an artms-swarm run folder) also: every CSV of it reads without
error, truth.oem reads and its epochs (TT ns from the UTC text) are the
navigation steps of nav/<observer>.csv, and t_utc of eval/targets.csv gives its
t_tt_ns. Run by tests/integration/campaign.sh.
"""
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..", "tools", "python"))
from artms_tools import (BodVerdict, FrameStatus, NavHealth, RunFolderError, SolutionSource, decode_track_id,  # noqa: E402
                         is_samus_track, read_csv, read_oem, read_summary, single_detection_target,
                         tt_ns_from_utc)

RUN_DIR = None


def write(dirname, name, text):
    path = os.path.join(dirname, name)
    with open(path, "w") as f:
        f.write(text)
    return path


class CsvTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.d = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def test_rows_by_name_with_their_line(self):
        p = write(self.d, "a.csv", "t_tt_ns,nees,status\n1,6.5,ok\n\n2,-nan,corrupt\n")
        t = read_csv(p, required=("nees",))
        self.assertEqual(t.columns, ["t_tt_ns", "nees", "status"])
        self.assertEqual([r.int("t_tt_ns") for r in t], [1, 2])
        self.assertEqual(t[0].float("nees"), 6.5)
        self.assertNotEqual(t[1].float("nees"), t[1].float("nees"))  # NaN
        self.assertEqual([r.line for r in t], [2, 4])

    def test_short_row_names_file_line_and_column(self):
        p = write(self.d, "b.csv", "a,b,c\n1,2,3\n4,5\n")
        with self.assertRaises(RunFolderError) as e:
            read_csv(p)
        self.assertIn(f"{p}:3:", str(e.exception))
        self.assertIn("'c'", str(e.exception))

    def test_long_row_is_an_error(self):
        p = write(self.d, "c.csv", "a,b\n1,2,3\n")
        with self.assertRaises(RunFolderError) as e:
            read_csv(p)
        self.assertIn(f"{p}:2:", str(e.exception))
        self.assertIn("'b'", str(e.exception))

    def test_bad_number_names_the_column(self):
        p = write(self.d, "d.csv", "frame,x_px\n1,abc\n")
        r = read_csv(p)[0]
        with self.assertRaises(RunFolderError) as e:
            r.float("x_px")
        self.assertIn(f"{p}:2: column 'x_px'", str(e.exception))
        with self.assertRaises(RunFolderError):
            r.int("x_px")
        with self.assertRaises(RunFolderError) as e:
            r["nope"]
        self.assertIn("no column 'nope'", str(e.exception))
        self.assertIsNone(r.get("nope"))

    def test_header_problems(self):
        with self.assertRaises(RunFolderError):
            read_csv(write(self.d, "e.csv", "a,a\n1,2\n"))
        with self.assertRaises(RunFolderError) as e:
            read_csv(write(self.d, "f.csv", "a,b\n1,2\n"), required=("nees",))
        self.assertIn("'nees'", str(e.exception))
        empty = read_csv(write(self.d, "g.csv", ""))
        self.assertEqual((list(empty), empty.columns), ([], []))

    def test_summary(self):
        with self.assertRaises(RunFolderError):
            read_summary(self.d)
        write(self.d, "summary.json", "[1]")
        with self.assertRaises(RunFolderError):
            read_summary(self.d)


class CodesTest(unittest.TestCase):
    def test_codes(self):
        self.assertEqual(NavHealth.parse("1"), NavHealth.REINITIALISING)
        self.assertEqual(NavHealth.parse("no solution"), NavHealth.NO_SOLUTION)
        self.assertEqual(NavHealth(1).label, "re-initialising")
        self.assertEqual(SolutionSource.parse(2).label, "GNSS")
        self.assertEqual(SolutionSource.parse("ground"), SolutionSource.GROUND)
        self.assertEqual([FrameStatus.parse(s) for s in ("ok", "no_detections", "not_identified", "corrupt", "end")],
                         [0, 1, 2, 3, 4])
        with self.assertRaises(ValueError):
            FrameStatus.parse("dropped")
        self.assertEqual(BodVerdict.parse("minimum_at_edge"), BodVerdict.MINIMUM_AT_EDGE)
        self.assertEqual(BodVerdict(6).label, "outside_tolerances")

    def test_track_ids(self):
        self.assertEqual(decode_track_id(-1), ("untracked", None))
        self.assertEqual(decode_track_id("7"), ("samus", 7))
        self.assertEqual(decode_track_id(-2), ("single", 0))
        self.assertEqual(decode_track_id(-4), ("single", 2))
        self.assertTrue(is_samus_track(0) and not is_samus_track(-1))
        self.assertEqual(single_detection_target(-3), 1)
        self.assertIsNone(single_detection_target(5))


OEM = """CCSDS_OEM_VERS = 2.0
CREATION_DATE = 2024-05-08T00:00:00.000000
ORIGINATOR = test

META_START
OBJECT_NAME = SV4
OBJECT_ID = SV4
CENTER_NAME = EARTH
REF_FRAME = EME2000
TIME_SYSTEM = UTC
START_TIME = 2024-05-08T00:00:00.000000
STOP_TIME = 2024-05-08T00:01:00.000000
META_STOP

COMMENT a comment
2024-05-08T00:00:00.000000 1.0 2.0 3.0 0.004 0.005 0.006
2024-05-08T00:01:00.000000 1.5 2.5 3.5 0.004 0.005 0.006
"""


class OemTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.d = self.tmp.name

    def tearDown(self):
        self.tmp.cleanup()

    def test_reads_m_and_tt(self):
        o = read_oem(write(self.d, "a.oem", OEM))
        s = o.segment("SV4")
        self.assertEqual(len(s), 2)
        self.assertEqual(s.r_m[0], (1000.0, 2000.0, 3000.0))
        self.assertAlmostEqual(s.v_mps[1][2], 6.0)
        self.assertEqual(s.t_tt_ns[1] - s.t_tt_ns[0], 60 * 10**9)
        self.assertEqual(s.t_tt_ns[0], tt_ns_from_utc("2024-05-08T00:00:00Z"))
        with self.assertRaises(KeyError):
            o.segment("SV9")

    def test_errors_name_the_line(self):
        cases = {
            "version": (OEM.replace("= 2.0", "= 1.0"), 1),
            "meta": (OEM.replace("TIME_SYSTEM = UTC\n", ""), 12),
            "outside": (OEM.replace("00:01:00.000000 1.5", "00:02:00.000000 1.5"), 17),
            "order": (OEM.replace("00:01:00.000000 1.5", "00:00:00.000000 1.5"), 17),
            "fields": (OEM.replace(" 0.006\n2024", "\n2024"), 16),
        }
        for what, (text, line) in cases.items():
            with self.subTest(what):
                with self.assertRaises(RunFolderError) as e:
                    read_oem(write(self.d, f"{what}.oem", text))
                self.assertIn(f"{what}.oem:{line}:", str(e.exception))


class TimeTest(unittest.TestCase):
    def test_j2000_and_leap_seconds(self):
        self.assertEqual(tt_ns_from_utc("2000-01-01T11:58:55.816Z"), 0)
        # A leap second (2016-12-31T23:59:60) between the two: 2 s of TT for 1 s of naive UTC.
        self.assertEqual(tt_ns_from_utc("2017-01-01T00:00:00Z") - tt_ns_from_utc("2016-12-31T23:59:59Z"), 2 * 10**9)
        with self.assertRaises(ValueError):
            tt_ns_from_utc("2024-02-30T00:00:00Z")

    def test_against_erfa(self):
        try:
            import erfa
        except ImportError:
            self.skipTest("python3-erfa not installed")
        for text, ymd, hms in [("2024-05-08T00:00:00Z", (2024, 5, 8), (0, 0, 0.0)),
                               ("2012-06-30T12:34:56.5Z", (2012, 6, 30), (12, 34, 56.5))]:
            u1, u2 = erfa.dtf2d("UTC", *ymd, *hms)
            t1, t2 = erfa.taitt(*erfa.utctai(u1, u2))
            tt_s = ((t1 - 2451545.0) + t2) * 86400.0
            self.assertAlmostEqual(tt_ns_from_utc(text) * 1e-9, tt_s, delta=1e-5)


class NeesSpreadTest(unittest.TestCase):
    """campaign.nees_spread_entry: the part of the run-average NEES common to the runs."""

    def series(self, rng, runs, steps, common=None):
        import numpy as np
        # chi2(6) per step, correlated over ~10 steps (a moving average), as a filter's NEES is.
        raw = rng.chisquare(6, size=(runs, steps + 9))
        m = np.array([np.convolve(r, np.ones(10) / 10, mode="valid") for r in raw])
        return m + (common if common is not None else 0.0)

    def test_independent_runs_have_no_common_part_and_a_shared_swing_is_found(self):
        import numpy as np
        sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..", "tools",
                                        "artms_swarm"))
        from campaign import nees_spread_entry
        rng = np.random.default_rng(7)
        alone = [nees_spread_entry(self.series(rng, 20, 600))["common_sd"] for _ in range(5)]
        self.assertLess(max(alone), 0.25, alone)
        swing = 1.2 * np.sin(np.arange(600) * 2 * np.pi / 150)  # sd 0.85, in every run alike
        found = [nees_spread_entry(self.series(rng, 20, 600, swing))["common_sd"] for _ in range(5)]
        self.assertTrue(all(0.7 < f < 1.0 for f in found), found)
        self.assertIsNone(nees_spread_entry(self.series(rng, 1, 600)))
        self.assertIsNone(nees_spread_entry(np.full((20, 600), np.nan)))


class RunFolderTest(unittest.TestCase):
    """On a real run folder (RUN_DIR), when given."""

    def setUp(self):
        if RUN_DIR is None:
            self.skipTest("no RUN_DIR given")

    def test_every_csv_reads(self):
        n = 0
        for root, _, files in os.walk(RUN_DIR):
            for fn in files:
                if fn.endswith(".csv"):
                    read_csv(os.path.join(root, fn))
                    n += 1
        self.assertGreater(n, 5)

    def test_truth_oem_epochs_are_the_navigation_steps(self):
        oem = read_oem(os.path.join(RUN_DIR, "truth.oem"))
        summary = read_summary(RUN_DIR)
        for obs in summary["observers"]:
            times = set(oem.segment(obs).t_tt_ns)
            nav = [r.int("t_tt_ns") for r in read_csv(os.path.join(RUN_DIR, "nav", f"{obs}.csv"))]
            self.assertTrue(nav and set(nav) <= times, obs)
            for r in read_csv(os.path.join(RUN_DIR, "nav", f"{obs}.csv")):
                NavHealth.parse(r["health"]), SolutionSource.parse(r["source"])

    def test_eval_utc_gives_tt(self):
        rows = read_csv(os.path.join(RUN_DIR, "eval", "targets.csv"), required=("t_utc", "t_tt_ns"))
        self.assertTrue(rows)
        for r in rows:
            self.assertEqual(tt_ns_from_utc(r["t_utc"]), r.int("t_tt_ns"), r.line)


if __name__ == "__main__":
    if len(sys.argv) > 1 and not sys.argv[1].startswith("-"):
        RUN_DIR = sys.argv.pop(1)
    unittest.main(verbosity=1)
