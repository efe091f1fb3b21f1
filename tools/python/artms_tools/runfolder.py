"""Reading an artms-swarm run folder (docs/runtime.md, "Run folder").

CSV files are read by column name. A malformed row is an error naming the
file, the line and the column, never a row silently dropped: a short or long
row, a duplicated or missing header column, a value that is not a number
where one is asked for.
"""
import csv
import json
import math
import os


class RunFolderError(ValueError):
    """A run-folder file that cannot be read as documented (message: file:line: what)."""


class Row(dict):
    """One CSV row: column name -> text, with the place it came from.

    row["x"] on a column the file does not have raises RunFolderError;
    row.get("x") stays lenient. int()/float() convert with an error that
    names file, line and column.
    """

    __slots__ = ("path", "line")

    def __missing__(self, key):
        raise RunFolderError(f"{self.path}:{self.line}: no column {key!r} (columns: {', '.join(self)})")

    def _where(self, name):
        return f"{self.path}:{self.line}: column {name!r}"

    def int(self, name):
        v = self[name]
        try:
            return int(v)
        except (TypeError, ValueError):
            raise RunFolderError(f"{self._where(name)}: {v!r} is not an integer") from None

    def float(self, name, empty=None):
        """float of the column; `empty` (e.g. math.nan) is returned for an empty field if given.

        'nan' and '-nan' (printf of a NaN) read as NaN.
        """
        v = self[name]
        if v == "" and empty is not None:
            return empty
        try:
            return float(v)
        except (TypeError, ValueError):
            raise RunFolderError(f"{self._where(name)}: {v!r} is not a number") from None


class Table(list):
    """Rows of one CSV file (a list of Row) with .path and .columns (header order)."""

    def __init__(self, path, columns, rows):
        super().__init__(rows)
        self.path = path
        self.columns = columns


def read_csv(path, required=()):
    """Reads a CSV file with a header line.

    Returns a Table (list of Row). A file of zero bytes gives an empty Table
    without columns; a header-only file an empty Table with its columns.
    Blank lines are skipped. Raises OSError when the file cannot be opened
    and RunFolderError for: a duplicated or empty header name, a column of
    `required` missing, a row whose field count differs from the header's,
    a CSV syntax error.
    """
    with open(path, newline="") as f:
        reader = csv.reader(f, strict=True)
        try:
            header = next(reader, None)
            if header is None:
                return Table(path, [], [])
            seen = set()
            for k, name in enumerate(header, start=1):
                if name == "":
                    raise RunFolderError(f"{path}:{reader.line_num}: header field {k} is empty")
                if name in seen:
                    raise RunFolderError(f"{path}:{reader.line_num}: header names column {name!r} twice")
                seen.add(name)
            missing = [c for c in required if c not in seen]
            if missing:
                raise RunFolderError(f"{path}:{reader.line_num}: no column {', '.join(map(repr, missing))} "
                                     f"(columns: {', '.join(header)})")
            n = len(header)
            rows = []
            for fields in reader:
                if not fields:
                    continue
                if len(fields) != n:
                    where = f"{path}:{reader.line_num}: {len(fields)} fields, the header has {n}"
                    if len(fields) < n:
                        raise RunFolderError(f"{where}: column {header[len(fields)]!r} (field {len(fields) + 1}) "
                                             f"and after missing")
                    raise RunFolderError(f"{where}: field {n + 1} ({fields[n]!r}) is beyond the last column "
                                         f"{header[-1]!r}")
                r = Row(zip(header, fields))
                r.path, r.line = path, reader.line_num
                rows.append(r)
        except csv.Error as e:
            raise RunFolderError(f"{path}:{reader.line_num}: {e}") from None
    return Table(path, list(header), rows)


def read_summary(run_dir):
    """summary.json of a run folder as a dict; RunFolderError if missing, unreadable or not an object."""
    path = os.path.join(run_dir, "summary.json")
    try:
        with open(path) as f:
            s = json.load(f)
    except FileNotFoundError:
        raise RunFolderError(f"{path}: missing") from None
    except (OSError, ValueError) as e:
        raise RunFolderError(f"{path}: {e}") from None
    if not isinstance(s, dict):
        raise RunFolderError(f"{path}: not a JSON object")
    return s


def failed_processes(summary):
    """Processes of a summary.json whose exit_code is not 0 (a missing exit_code counts as failed)."""
    return [p for p in summary.get("processes", []) if not isinstance(p, dict) or p.get("exit_code") != 0]


def target_nees(run_dir):
    """NEES of eval/targets.csv: {(observer, target): {t_tt_ns: nees}} (NaN where the covariance was unusable).

    A later row of the same pair and time replaces an earlier one.
    """
    t = read_csv(os.path.join(run_dir, "eval", "targets.csv"), required=("observer", "target", "t_tt_ns", "nees"))
    out = {}
    for r in t:
        out.setdefault((r["observer"], r["target"]), {})[r.int("t_tt_ns")] = r.float("nees")
    return out


ROE_NAMES = ("da", "dlambda", "dex", "dey", "dix", "diy")


def target_normalised_errors(run_dir):
    """Each ROE's error over its 1-sigma in eval/targets.csv: {(observer, target): {t_tt_ns: [6 floats]}}
    (NaN where the 1-sigma is not positive). A later row of the same pair and time replaces an earlier one."""
    t = read_csv(os.path.join(run_dir, "eval", "targets.csv"),
                 required=("observer", "target", "t_tt_ns") + tuple(f"err_a_{n}_m" for n in ROE_NAMES)
                 + tuple(f"sigma_a_{n}_m" for n in ROE_NAMES))
    out = {}
    for r in t:
        z = []
        for n in ROE_NAMES:
            sig = r.float(f"sigma_a_{n}_m")
            z.append(r.float(f"err_a_{n}_m") / sig if sig > 0 else math.nan)
        out.setdefault((r["observer"], r["target"]), {})[r.int("t_tt_ns")] = z
    return out


def principal_z2(cov_upper, err):
    """(error / 1-sigma)^2 along the principal directions of a 6x6 covariance given by its upper triangle row by
    row (21 numbers, the units of err squared), thinnest direction first; their sum is the NEES. None when the
    covariance is not positive definite."""
    import numpy as np
    P = np.zeros((6, 6))
    P[np.triu_indices(6)] = [float(x) for x in cov_upper]
    P = P + P.T - np.diag(np.diag(P))
    if not np.all(np.isfinite(P)):
        return None
    w, V = np.linalg.eigh(P)
    if not w[0] > 0:
        return None
    return [float(x) for x in (V.T @ np.asarray(err, dtype=float)) ** 2 / w]


def target_principal_errors(run_dir):
    """Each target's error along its covariance's principal directions: {(observer, target): {t_tt_ns:
    [6 floats]}}, the squared error over the variance along each eigenvector of nav/targets.csv's ROE
    covariance, thinnest direction first (their sum is the NEES; each is 1 on average for a consistent
    filter). Errors from eval/targets.csv, in the covariance's units through the ratio of the two files'
    1-sigmas (the observer's a). Empty when the run folder predates the covariance_upper column."""
    import numpy as np
    nav = read_csv(os.path.join(run_dir, "nav", "targets.csv"), required=("observer", "target", "t_tt_ns"))
    if "covariance_upper" not in nav.columns:
        return {}
    ev = read_csv(os.path.join(run_dir, "eval", "targets.csv"),
                  required=("observer", "target", "t_tt_ns") + tuple(f"err_a_{n}_m" for n in ROE_NAMES)
                  + tuple(f"sigma_a_{n}_m" for n in ROE_NAMES))
    errors = {(r["observer"], r["target"], r.int("t_tt_ns")): r for r in ev}
    out = {}
    for r in nav:
        e = errors.get((r["observer"], r["target"], r.int("t_tt_ns")))
        upper = (r["covariance_upper"] or "").split()
        if e is None or len(upper) != 21:
            continue
        ratio = [e.float(f"sigma_a_{n}_m") / r.float(f"sigma_{n}") for n in ROE_NAMES
                 if r.float(f"sigma_{n}") > 0]
        if not ratio:
            continue
        err = np.array([e.float(f"err_a_{n}_m") for n in ROE_NAMES]) / float(np.mean(ratio))
        z2 = principal_z2(upper, err)
        if z2 is not None:
            out.setdefault((r["observer"], r["target"]), {})[r.int("t_tt_ns")] = z2
    return out


def observer_nees(run_dir):
    """Absolute position NEES (3 dof) of eval/observers.csv: {observer: {t_tt_ns: nees}}; empty when the run
    folder predates the nees_pos column."""
    path = os.path.join(run_dir, "eval", "observers.csv")
    if not os.path.exists(path):
        return {}
    t = read_csv(path, required=("observer", "t_tt_ns"))
    if "nees_pos" not in t.columns:
        return {}
    out = {}
    for r in t:
        out.setdefault(r["observer"], {})[r.int("t_tt_ns")] = r.float("nees_pos")
    return out


def target_nis(run_dir):
    """Cumulative bearing NIS of nav/targets.csv: {(observer, target): {t_tt_ns: (nis_sum, updates)}};
    empty when the run folder predates the bearing_nis_sum column."""
    path = os.path.join(run_dir, "nav", "targets.csv")
    t = read_csv(path, required=("observer", "target", "t_tt_ns"))
    if "bearing_nis_sum" not in t.columns:
        return {}
    out = {}
    for r in t:
        out.setdefault((r["observer"], r["target"]), {})[r.int("t_tt_ns")] = (r.float("bearing_nis_sum"),
                                                                               r.int("bearing_updates"))
    return out


def finite(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
