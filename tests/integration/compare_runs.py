#!/usr/bin/python3
"""compare_runs.py A B [C ...]: every run folder holds the same files with the
same bytes, apart from timing.json and logs/ (DESIGN.md section 3), and every
process of its summary.json exited with 0. Prints one line; exit 1 naming the
files that differ."""
import filecmp, json, os, sys


def files(root):
    out = []
    for d, _, fs in os.walk(root):
        for f in fs:
            rel = os.path.relpath(os.path.join(d, f), root)
            if rel == "timing.json" or rel.startswith("logs" + os.sep):
                continue
            out.append(rel)
    return sorted(out)


def main():
    runs = sys.argv[1:]
    if len(runs) < 2:
        sys.exit(__doc__)
    for r in runs:
        s = json.load(open(os.path.join(r, "summary.json")))
        bad = [p for p in s["processes"] if p["exit_code"] != 0]
        if bad:
            sys.exit(f"{r}: processes with non-zero exit: {bad}")
    ref = files(runs[0])
    for r in runs[1:]:
        other = files(r)
        if ref != other:
            sys.exit(f"{runs[0]} and {r}: different file sets: {sorted(set(ref) ^ set(other))}")
        diff = [f for f in ref if not filecmp.cmp(os.path.join(runs[0], f), os.path.join(r, f), shallow=False)]
        if diff:
            sys.exit(f"{runs[0]} and {r}: files differ: {diff}")
    print(f"{len(runs)} run folders, {len(ref)} files each, byte-identical (timing.json and logs/ aside)")


if __name__ == "__main__":
    main()
