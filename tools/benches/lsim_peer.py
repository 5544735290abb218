#!/usr/bin/env python3
"""Peer for `beamtool bench-sim`: scipy.signal.lsim on the same state-space model and input.

Reads the JSON written by the Rust side (A, B, C, D, dt, u), runs lsim 5 times, prints the
median wall time and the output as JSON on stdout.
"""
import json
import sys
import time

import numpy as np
from scipy import signal

d = json.load(open(sys.argv[1]))
A, B, C, D = (np.array(d[k], dtype=float) for k in ("A", "B", "C", "D"))
u = np.array(d["u"], dtype=float)
t = np.arange(len(u)) * d["dt"]
sys_ = signal.StateSpace(A, B, C, D)
times = []
for _ in range(5):
    t0 = time.perf_counter()
    _, y, _ = signal.lsim(sys_, u, t, interp=False)
    times.append(time.perf_counter() - t0)
print(json.dumps({"median_s": float(np.median(times)), "y": [float(v) for v in np.ravel(y)]}))
