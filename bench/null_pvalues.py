#!/usr/bin/env python3
"""Are the diagnosis' p-values uniform on recordings without any catalogue effect?

Reads every `diagnosis.json` (or `caseNN.json`) under the given directories, keeps the null
cases, and tests the p-values of their candidates (`candidates[].p_value`, the Diebold–Mariano
test of docs/diagnose.md) against the uniform distribution with the one-sample
Kolmogorov–Smirnov statistic D and its 5 % critical value 1.36/√n (Massey 1951, large n).
`servo_lag` is left out: every rig of the shared sets has a position loop its rig file does not
describe, so the loop is true physics there, not a null candidate.

A case is a null when its directory holds a `truth.json` with no effects (the own generator,
`beamtool diagnose-proof`), or when `--key` (a shared set's key.json) says its kind is `null`.
Every replicate of a `beamtool diagnose-bootstrap` output directory (listed in its
`bootstrap.json`) is a null too, and there `servo_lag` counts: a replicate has no loop.

Usage (standard library only):
    python3 bench/null_pvalues.py DIR [DIR ...] [--key ../shared/data/independent-v2/…/key.json]
Prints n, D, the critical value, a 10-bin histogram and how many p-values fall below 0.001.
"""
import argparse
import json
import math
import os


def null_jsons(root, key):
    """(path, whether servo_lag is a null candidate there) of every null diagnosis under root."""
    for dirpath, _, files in os.walk(root):
        if "bootstrap.json" in files:
            for r in json.load(open(os.path.join(dirpath, "bootstrap.json")))["replicates"]:
                yield os.path.join(dirpath, r["file"]), True
            continue
        for name in files:
            path = os.path.join(dirpath, name)
            if name == "diagnosis.json":
                truth = os.path.join(os.path.dirname(dirpath), "truth.json")
                if os.path.exists(truth) and not json.load(open(truth)).get("effects"):
                    yield path, False
            elif key and name.endswith(".json") and key.get(name[:-5], {}).get("kind") == "null":
                yield path, False


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--key", help="a shared set's key.json (names the null cases)")
    a = ap.parse_args()
    key = json.load(open(a.key)) if a.key else None
    ps, cases, alarms = [], 0, 0
    for d in a.dirs:
        for path, loop_is_null in null_jsons(d, key):
            cases += 1
            j = json.load(open(path))
            named = [e for e in j.get("effects", []) if loop_is_null or e.get("effect") != "servo_lag"]
            alarms += bool(named) or bool(j.get("unexplained"))
            for c in j.get("candidates", []):
                p = c.get("p_value")
                if p is not None and (loop_is_null or c.get("effect") != "servo_lag"):
                    ps.append(float(p))
    if not ps:
        raise SystemExit("no null case with candidate p-values found under " + ", ".join(a.dirs))
    ps.sort()
    n = len(ps)
    d = max(max((i + 1) / n - p, p - i / n) for i, p in enumerate(ps))
    bins = [0] * 10
    for p in ps:
        bins[min(int(p * 10), 9)] += 1
    print(f"{cases} null cases, {alarms} with a false alarm (a name or `unexplained`); "
          f"{n} candidate p-values: KS D = {d:.3f} "
          f"(uniform at 5 % if below {1.36 / math.sqrt(n):.3f})")
    print("histogram (0-0.1 … 0.9-1):", bins)
    print(f"below 0.001: {sum(p < 1e-3 for p in ps)} (uniform: {n * 1e-3:.1f})")


if __name__ == "__main__":
    main()
