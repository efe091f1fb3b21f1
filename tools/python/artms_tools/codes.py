"""The integer codes of the run folder, decoded in one place.

Values as the IDL (idl/artms.idl) and the recorder write them:
  nav/<observer>.csv, eval/observers.csv  health, source
  isl.csv                                 source
  imp/<observer>/attitude.csv             status (written as its name: ok, ...)
  imp/<observer>/measurements.csv         track_id
  bod/<observer>.csv                      verdict (verdict_name writes the label)
"""
import enum


class _Coded(enum.IntEnum):
    """An IntEnum with a printable label and a tolerant parser."""

    @property
    def label(self):
        return self._labels()[self.value]

    @classmethod
    def parse(cls, value):
        """Member from an int, a digit string ("2") or a name/label ("no_solution", "no solution").

        Raises ValueError naming the accepted values.
        """
        if isinstance(value, cls):
            return value
        text = str(value).strip()
        try:
            return cls(int(text))
        except ValueError:
            pass
        key = text.lower().replace("-", "_").replace(" ", "_")
        for m in cls:
            if key in (m.name.lower(), m.label.lower().replace("-", "_").replace(" ", "_")):
                return m
        accepted = ", ".join(f"{m.value} {m.label}" for m in cls)
        raise ValueError(f"{cls.__name__}: {value!r} is none of {accepted}")


class NavHealth(_Coded):
    """Filter health of a navigation telemetry row (IDL NavTelemetry.health)."""
    HEALTHY = 0
    REINITIALISING = 1
    NO_SOLUTION = 2

    @staticmethod
    def _labels():
        return {0: "healthy", 1: "re-initialising", 2: "no solution"}


class SolutionSource(_Coded):
    """Source of an absolute orbit (nav telemetry, ISL broadcasts)."""
    NONE = 0
    SOD = 1
    GNSS = 2
    GROUND = 3

    @staticmethod
    def _labels():
        return {0: "none", 1: "SOD", 2: "GNSS", 3: "ground"}


class FrameStatus(_Coded):
    """IMP's outcome for one frame (attitude.csv writes the label)."""
    OK = 0
    NO_DETECTIONS = 1
    NOT_IDENTIFIED = 2
    CORRUPT = 3
    END = 4

    @staticmethod
    def _labels():
        return {0: "ok", 1: "no_detections", 2: "not_identified", 3: "corrupt", 4: "end"}


class Severity(_Coded):
    """Event severity (events.log writes the label)."""
    INFO = 0
    WARNING = 1
    ERROR = 2

    @staticmethod
    def _labels():
        return {0: "info", 1: "warning", 2: "error"}


class BodVerdict(_Coded):
    """BOD's verdict on an attempt (IDL BodAttempt.verdict; bod/<observer>.csv verdict, verdict_name)."""
    USABLE = 0
    TOO_FEW_MEASUREMENTS = 1
    BAD_INPUT = 2
    NOT_CONVERGED = 3
    MINIMUM_AT_EDGE = 4
    FLAT_RESIDUAL_CURVE = 5
    OUTSIDE_TOLERANCES = 6

    @staticmethod
    def _labels():
        return {0: "usable", 1: "too_few_measurements", 2: "bad_input", 3: "not_converged",
                4: "minimum_at_edge", 5: "flat_residual_curve", 6: "outside_tolerances"}


# track_id of imp/<observer>/measurements.csv:
#   -1    untracked (no SAMUS track, not assigned)
#   >= 0  SAMUS track id
#   <= -2 single detection assigned by SOD to target index -2 - track_id
UNTRACKED = -1


def is_samus_track(track_id):
    return int(track_id) >= 0


def single_detection_target(track_id):
    """Target index of a single detection (track_id <= -2), else None."""
    t = int(track_id)
    return -2 - t if t <= -2 else None


def decode_track_id(track_id):
    """('untracked', None) | ('samus', track) | ('single', target index)."""
    t = int(track_id)
    if t >= 0:
        return ("samus", t)
    if t == UNTRACKED:
        return ("untracked", None)
    return ("single", -2 - t)
