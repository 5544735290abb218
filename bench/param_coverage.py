#!/usr/bin/env python3
"""±2σ coverage of the diagnosis's named parameters against the truth, over every set together.

The issue's target: of the parameters of correctly named effects, at least 90 % lie within two
reported standard deviations of the truth, over at least 30 parameters of all sets together, with
the median relative σ beside it (coverage is not to be bought with width).

Inputs (any subset):
  --v2 KEEP_DIR KEY      kept JSONs of the second shared set (one `caseNN.json` per case) and its key.json
  --v1 KEEP_DIR KEY      the same for the first shared set (`hidden_gen/key.json`)
  --proof PROOF_JSON     a `beamtool diagnose-proof` run (its `estimates`), repeatable

A parameter counts when the effect that owns it is named and is a true effect of the case, and the
truth gives the same parameter by name (a loop's parameters are not compared: the keys hold another
filter). The σ is the reported 1 σ (`effects[].uncertainty`; a proof run's `sigma`).
Standard library only.
"""
import argparse
import json
import os
import statistics

# parameters the shared sets' scorers compare (both scorers' lists)
COMPARED = {"friction_n", "tip_mass_kg", "root_stiffness_nm_per_rad", "sensor_delay_s", "mount_frequency_hz",
            "cogging_amplitude_n", "cogging_pitch_m", "drag_coefficient_kg_per_m2"}


def from_keep(keep, key, set_name):
    rows = []
    for case, truth in sorted(key.items()):
        path = os.path.join(keep, case + ".json")
        if not os.path.exists(path):
            continue
        res = json.load(open(path))
        true_effects = truth.get("effects") or [truth.get("effect")]
        for e in res.get("effects") or []:
            if not isinstance(e, dict) or e.get("effect") not in true_effects:
                continue
            for name, value in (e.get("parameters") or {}).items():
                t = (truth.get("parameters") or {}).get(name)
                sd = (e.get("uncertainty") or {}).get(name)
                if name in COMPARED and all(isinstance(v, (int, float)) for v in (t, value, sd)):
                    rows.append((set_name, case, name, value, sd, t))
    return rows


def from_proof(path):
    rows = []
    for case in json.load(open(path)):
        if not case.get("correct") or case.get("group") == "null":
            continue
        for est in case.get("estimates") or []:
            name = est.get("kind", "")
            if "(calibration)" in name or name.startswith("servo_"):
                continue
            v, sd, t = est.get("value"), est.get("sigma"), est.get("truth")
            if all(isinstance(x, (int, float)) for x in (v, sd, t)):
                rows.append((os.path.basename(os.path.dirname(path)), str(case.get("seed")), name, v, sd, t))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--v2", nargs=2, metavar=("KEEP", "KEY"))
    ap.add_argument("--v1", nargs=2, metavar=("KEEP", "KEY"))
    ap.add_argument("--proof", action="append", default=[])
    a = ap.parse_args()
    rows = []
    if a.v2:
        rows += from_keep(a.v2[0], json.load(open(a.v2[1])), "second set")
    if a.v1:
        rows += from_keep(a.v1[0], json.load(open(a.v1[1])), "first set")
    for p in a.proof:
        rows += from_proof(p)
    if not rows:
        raise SystemExit("no named parameter with a truth and a 1 σ in the inputs")
    for s, case, name, v, sd, t in rows:
        z = (v - t) / sd if sd > 0 else float("inf")
        print(f"{s:12s} {case:8s} {name:28s} {v:+.4e} ± {sd:.2e}  truth {t:+.4e}  z {z:+6.2f}  "
              f"{'in' if abs(z) <= 2 else 'OUT'}")
    inside = sum(1 for *_, v, sd, t in rows if sd > 0 and abs(v - t) <= 2 * sd)
    rel = [sd / abs(t) for *_, v, sd, t in rows if t != 0]
    print(f"±2σ coverage {inside}/{len(rows)} = {100 * inside / len(rows):.0f} % "
          f"(target ≥ 90 % over ≥ 30); median relative σ {100 * statistics.median(rel):.1f} %")


if __name__ == "__main__":
    main()
