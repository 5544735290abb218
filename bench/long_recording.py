#!/usr/bin/env python3
"""Makes the long-recording benchmark's input: a `beamtool simulate` recording (time_s,
base_cmd_m, base_pos_m, tip_pos_m, force_n) turned into what a logger writes — four columns
(force dropped), the base quantised to a 1 um encoder, 20 um Gaussian camera noise on the tip
(the virtual rig's sensors, tools/src/board/rig.rs), 7 significant digits.

With --repeat N the simulated recording is played N times end to end (each run starts and ends
at rest; the time base continues), e.g. ten 1 000 s sweeps for a 10 M-row file.

Usage:
    python3 bench/long_recording.py SIM.csv OUT.csv [--seed 1] [--repeat 1]
Needs numpy. Not a dependency of the tools: a script beside the benchmarks.
"""
import argparse
import numpy as np


COLUMNS = ["time_s", "base_cmd_m", "base_pos_m", "tip_pos_m"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("sim")
    ap.add_argument("out")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    with open(a.sim) as f:
        names = f.readline().strip().split(",")
    d = np.loadtxt(a.sim, delimiter=",", skiprows=1, usecols=[names.index(c) for c in COLUMNS])
    if a.repeat > 1:
        span = d[-1, 0] - d[0, 0] + (d[1, 0] - d[0, 0])
        d = np.concatenate([d + np.array([k * span, 0.0, 0.0, 0.0]) for k in range(a.repeat)])
    rng = np.random.default_rng(a.seed)
    t, cmd = d[:, 0], d[:, 1]
    base = np.round(d[:, 2] / 1e-6) * 1e-6
    tip = d[:, 3] + rng.normal(0.0, 20e-6, t.size)
    cols = np.column_stack([t, cmd, base, tip])
    np.savetxt(a.out, cols, delimiter=",", fmt=["%.3f", "%.7g", "%.7g", "%.7g"],
               header=",".join(COLUMNS), comments="")


if __name__ == "__main__":
    main()
