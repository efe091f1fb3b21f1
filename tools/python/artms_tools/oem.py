"""CCSDS OEM 2.0 (KVN) reader, the rules of common/io's read_oem, and UTC -> TT.

The run folder's truth.oem (and artms-propagate --oem) hold positions in km
and velocities in km/s, EME2000, UTC epochs "YYYY-MM-DDThh:mm:ss.ffffff".
read_oem returns them in m and m/s with each epoch also as TT nanoseconds
since J2000.0 (the time scale of every other file of the run folder).
"""
import calendar
import re

from .runfolder import RunFolderError

# TAI - UTC from the given UTC date on (IERS Bulletin C); the table of
# common/astro/src/time.cpp.
_LEAP_SECONDS = [
    ((1972, 1, 1), 10), ((1972, 7, 1), 11), ((1973, 1, 1), 12), ((1974, 1, 1), 13),
    ((1975, 1, 1), 14), ((1976, 1, 1), 15), ((1977, 1, 1), 16), ((1978, 1, 1), 17),
    ((1979, 1, 1), 18), ((1980, 1, 1), 19), ((1981, 7, 1), 20), ((1982, 7, 1), 21),
    ((1983, 7, 1), 22), ((1985, 7, 1), 23), ((1988, 1, 1), 24), ((1990, 1, 1), 25),
    ((1991, 1, 1), 26), ((1992, 7, 1), 27), ((1993, 7, 1), 28), ((1994, 7, 1), 29),
    ((1996, 1, 1), 30), ((1997, 7, 1), 31), ((1999, 1, 1), 32), ((2006, 1, 1), 33),
    ((2009, 1, 1), 34), ((2012, 7, 1), 35), ((2015, 7, 1), 36), ((2017, 1, 1), 37),
]
_TT_MINUS_TAI_NS = 32_184_000_000
_NS_PER_DAY = 86_400 * 10**9
_UTC_RE = re.compile(r"^(\d{4})-(\d{2})-(\d{2})[T ](\d{2}):(\d{2}):(\d{2})(?:\.(\d{1,9}))?Z?$")


def _days_from_civil(y, m, d):
    """Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm)."""
    y -= m <= 2
    era = y // 400
    yoe = y - era * 400
    doy = (153 * (m + (-3 if m > 2 else 9)) + 2) // 5 + d - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


_DAYS_TO_2000 = _days_from_civil(2000, 1, 1)


def tt_ns_from_utc(text):
    """TT nanoseconds since J2000.0 of a UTC string "YYYY-MM-DDThh:mm:ss[.f...][Z]".

    Raises ValueError on anything else or on a date before 1972 (leap-second table).
    """
    m = _UTC_RE.match(text.strip())
    if not m:
        raise ValueError(f"invalid UTC time {text!r} (expected YYYY-MM-DDThh:mm:ss[.fff][Z])")
    y, mo, d, hh, mm, ss = (int(g) for g in m.groups()[:6])
    frac = m.group(7) or ""
    if not (1 <= mo <= 12 and 1 <= d <= calendar.monthrange(y, mo)[1] and hh <= 23 and mm <= 59 and ss <= 60):
        raise ValueError(f"invalid UTC time {text!r}: field out of range")
    if (y, mo, d) < (1972, 1, 1):
        raise ValueError(f"UTC time {text!r} before 1972-01-01 (leap-second table)")
    tai_minus_utc = [v for start, v in _LEAP_SECONDS if (y, mo, d) >= start][-1]
    ns_of_day = ((hh * 60 + mm) * 60 + ss) * 10**9 + int(frac.ljust(9, "0") or 0)
    naive = (_days_from_civil(y, mo, d) - _DAYS_TO_2000) * _NS_PER_DAY + ns_of_day - _NS_PER_DAY // 2
    return naive + tai_minus_utc * 10**9 + _TT_MINUS_TAI_NS


class Segment:
    """One ephemeris block: object_name, object_id, meta (dict), and per sample
    epoch_utc (text), t_tt_ns (int), r_m and v_mps ((x, y, z) tuples, ECI EME2000)."""

    def __init__(self, meta):
        self.meta = dict(meta)
        self.object_name = meta["OBJECT_NAME"]
        self.object_id = meta["OBJECT_ID"]
        self.epoch_utc, self.t_tt_ns, self.r_m, self.v_mps = [], [], [], []

    def __len__(self):
        return len(self.t_tt_ns)


class Oem:
    """header (dict: CCSDS_OEM_VERS, CREATION_DATE, ORIGINATOR) and segments (list of Segment)."""

    def __init__(self):
        self.header = {}
        self.segments = []

    def segment(self, object_name):
        """The first segment of an object; KeyError naming the objects present."""
        for s in self.segments:
            if s.object_name == object_name:
                return s
        raise KeyError(f"no OEM segment for {object_name!r} (objects: {', '.join(s.object_name for s in self.segments)})")


_MANDATORY_META = ("OBJECT_NAME", "OBJECT_ID", "CENTER_NAME", "REF_FRAME", "TIME_SYSTEM", "START_TIME", "STOP_TIME")


def read_oem(path):
    """Reads a CCSDS OEM 2.0 KVN file as common/io's read_oem does.

    Supported: TIME_SYSTEM = UTC, REF_FRAME = EME2000; COMMENT lines and
    covariance blocks are skipped; optional accelerations after the six
    numbers are accepted and dropped. Raises RunFolderError "path:line: why"
    for anything else: missing header or META keywords, malformed data lines,
    epochs outside START_TIME..STOP_TIME or not strictly increasing, no
    segment, a segment without data.
    """
    oem = Oem()
    state, meta, seg = "header", {}, None
    start = stop = None
    line_no = 0

    def fail(why):
        raise RunFolderError(f"{path}:{line_no}: {why}")

    def tt(text):
        try:
            return tt_ns_from_utc(text)
        except ValueError as e:
            fail(str(e))

    with open(path) as f:
        for raw in f:
            line_no += 1
            line = raw.strip()
            if not line or line.startswith("COMMENT"):
                continue
            key, eq, value = (s.strip() for s in line.partition("="))
            if line == "META_START":
                if state == "meta":
                    fail("META_START inside a META block")
                if not all(k in oem.header for k in ("CCSDS_OEM_VERS", "CREATION_DATE", "ORIGINATOR")):
                    fail("header lacks CCSDS_OEM_VERS, CREATION_DATE or ORIGINATOR")
                state, meta = "meta", {}
            elif line == "META_STOP":
                if state != "meta":
                    fail("META_STOP without META_START")
                for k in _MANDATORY_META:
                    if k not in meta:
                        fail(f"META block lacks mandatory keyword {k}")
                if meta["TIME_SYSTEM"] != "UTC":
                    fail("only TIME_SYSTEM = UTC is supported")
                if meta["REF_FRAME"] != "EME2000":
                    fail("only REF_FRAME = EME2000 is supported")
                start, stop = tt(meta["START_TIME"]), tt(meta["STOP_TIME"])
                seg = Segment(meta)
                oem.segments.append(seg)
                state = "data"
            elif line == "COVARIANCE_START":
                state = "covariance"
            elif line == "COVARIANCE_STOP":
                state = "data"
            elif state == "header":
                if key == "CCSDS_OEM_VERS" and value != "2.0":
                    fail(f"CCSDS_OEM_VERS is '{value}', expected 2.0")
                if key == "CREATION_DATE":
                    tt(value)
                if key not in ("CCSDS_OEM_VERS", "CREATION_DATE", "ORIGINATOR"):
                    fail(f"unexpected header line '{line}'")
                oem.header[key] = value
            elif state == "meta":
                if not eq:
                    fail("expected KEY = value in META block")
                meta[key] = value
            elif state == "data":
                fields = line.split()
                if len(fields) not in (7, 10):
                    fail("data line needs an epoch and six numbers (optionally three accelerations)")
                try:
                    v = [float(x) for x in fields[1:]]
                except ValueError:
                    fail("malformed data line")
                t = tt(fields[0])
                if t < start or t > stop:
                    fail(f"epoch {fields[0]} outside START_TIME..STOP_TIME")
                if seg.t_tt_ns and t <= seg.t_tt_ns[-1]:
                    fail("epochs not strictly increasing")
                seg.epoch_utc.append(fields[0])
                seg.t_tt_ns.append(t)
                seg.r_m.append((v[0] * 1e3, v[1] * 1e3, v[2] * 1e3))
                seg.v_mps.append((v[3] * 1e3, v[4] * 1e3, v[5] * 1e3))
    if state == "meta":
        fail("file ends inside a META block")
    if not oem.segments:
        fail("no ephemeris segment (META_START ... META_STOP) found")
    for s in oem.segments:
        if not s.t_tt_ns:
            fail(f"segment {s.object_name} has no data lines")
    return oem
