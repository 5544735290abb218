#!/usr/bin/env python3
"""Which single condition of the diagnosis' rule stops which candidate, read from kept JSONs.

usage: python3 bench/stopped_alone.py KEEP_DIR [KEEP_DIR ...] [--key KEY.json ...] [--condition NAME]

KEEP_DIR holds `caseNN.json`, the JSON `beamtool diagnose --json` wrote for each case (a wrapper
around the binary keeps them while a scorer runs). A candidate is listed when exactly one
condition of its `reason` failed (the conditions are joined by "; "); the predictive test counts
as one. With `--key` (a set's key.json, the same order as the directories, or one for all), each
candidate is marked `true` when its effect is one of the case's effects, else `wrong`.
`--condition` keeps one of: test, allowance, accuracy, band, search_limit, wald, other.
Standard library only.
"""
import argparse
import glob
import json
import os
import sys

# (name, a phrase of the reason that says the condition failed)
CONDITIONS = [
    ("test", "predicts the validation recording no better"),
    ("allowance", "does not beat the model-form allowance"),
    ("accuracy", "within the model's stated accuracy"),
    ("band", "observable band"),
    ("search_limit", "at the limit of its search range"),
    ("wald", "σ from zero"),
]
# reasons that are not a failed condition: the candidate passed, or lost to another form
PASSES = ("passes every guard", "passes the guard", "another form of")


def failed_conditions(reason):
    """The failed conditions of a candidate's `reason`, by name (`other: …` when unknown)."""
    if any(reason.startswith(p) for p in PASSES):
        return []
    found = []
    for part in reason.split("; "):
        name = next((n for n, phrase in CONDITIONS if phrase in part), None)
        found.append(name or "other: " + part[:60])
    return found


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("keep", nargs="+")
    ap.add_argument("--key", action="append", default=[])
    ap.add_argument("--condition")
    a = ap.parse_args()
    if a.key and len(a.key) not in (1, len(a.keep)):
        sys.exit("--key: give one key for all directories or one per directory")
    rows = []
    for i, keep in enumerate(a.keep):
        key = {}
        if a.key:
            with open(a.key[min(i, len(a.key) - 1)]) as f:
                key = json.load(f)
        files = sorted(glob.glob(os.path.join(keep, "case*.json")))
        if not files:
            sys.exit(f"{keep}: no caseNN.json")
        for path in files:
            case = os.path.basename(path)[: -len(".json")]
            with open(path) as f:
                d = json.load(f)
            truth = key.get(case, {})
            for c in d.get("candidates", []):
                failed = failed_conditions(c.get("reason", ""))
                if len(failed) != 1:
                    continue
                cond = failed[0].split(":")[0]
                if a.condition and cond != a.condition:
                    continue
                mark = ""
                if truth:
                    mark = "true" if c["effect"] in truth.get("effects", []) else "wrong"
                rows.append((cond, keep, case, truth.get("kind", ""), c["effect"], c.get("predictive_z"), mark, c["reason"]))
    for cond in sorted({r[0] for r in rows}):
        sel = [r for r in rows if r[0] == cond]
        counts = {m: sum(1 for r in sel if r[6] == m) for m in ("true", "wrong")}
        print(f"== {cond}: {len(sel)} candidates" + (f" ({counts['true']} true, {counts['wrong']} wrong)" if a.key else ""))
        for _, keep, case, kind, effect, z, mark, reason in sel:
            zs = f"z {z:.1f}" if isinstance(z, (int, float)) else "z -"
            print(f"  {os.path.basename(os.path.normpath(keep))}/{case} {kind:7s} {effect:20s} {zs:8s} {mark:5s} {reason[:150]}")


if __name__ == "__main__":
    main()
