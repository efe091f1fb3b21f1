"""Python helpers shared by the ARTMS tools and tests (run folders, codes, OEM).

Scripts find this package through sys.path relative to their own file
(tools/python/); see tools/python/README.md.
"""
from .codes import (BodVerdict, FrameStatus, NavHealth, Severity, SolutionSource, UNTRACKED, decode_track_id,  # noqa: F401
                    is_samus_track, single_detection_target)
from .oem import Oem, Segment, read_oem, tt_ns_from_utc  # noqa: F401
from .runfolder import (Row, RunFolderError, Table, failed_processes, read_csv, read_summary,  # noqa: F401
                        target_nees, target_nis, target_normalised_errors)

__all__ = ["BodVerdict", "FrameStatus", "NavHealth", "Severity", "SolutionSource", "UNTRACKED", "decode_track_id", "is_samus_track",
           "single_detection_target", "Oem", "Segment", "read_oem", "tt_ns_from_utc", "Row", "RunFolderError", "Table",
           "failed_processes", "read_csv", "read_summary", "target_nees", "target_nis",
           "target_normalised_errors"]
