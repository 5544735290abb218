#!/usr/bin/env python3
"""The named peer of `beamtool identify FILE --bench`: the same work with scipy and sdypy-EMA.

    python3 bench/identify_peer.py FILE.csv --q 14 --nperseg 0 --window boxcar \
        --band 0.07,8.3 --order 32 --near 1.1047,6.9228

On the recording CSV (time_s, base_pos_m, tip_pos_m; base_cmd_m ignored):
  1. read: numpy.loadtxt;
  2. decimate: scipy.signal.decimate(q, ftype="fir", zero_phase=True) of base and tip;
  3. FRF: H1 = Pxy / Pxx by scipy.signal.csd / welch (x = base acceleration, the second
     difference of base_pos_m; y = tip deflection tip_pos_m - base_pos_m), segments of
     `nperseg` samples (0 = the whole record) with 50 % overlap, mean removed;
  4. LSCF: sdypy-EMA's `get_poles("lscf")` up to `order` on `band`, then
     `select_closest_poles(near)` (the modes beamtool found; stability within 1 % in f and
     5 % in zeta, the relaxed criteria of bench/sdypy_peer.py).
Prints one JSON line: seconds per stage, peak RSS (MB), modes (f Hz, zeta), versions.
Needs numpy, scipy and sdypy-EMA (pip install numpy scipy sdypy-EMA) — in a venv of its own,
not the project's. Exits 2 with a message when one is missing.
"""
import argparse, json, resource, sys, time


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("recording")
    ap.add_argument("--q", type=int, default=1, help="decimation factor")
    ap.add_argument("--nperseg", type=int, default=0, help="Welch segment (samples after decimation); 0 = whole record")
    ap.add_argument("--window", default="hamming", help="scipy window name (boxcar, hamming)")
    ap.add_argument("--band", default="0.1,10", help="f_lo,f_hi (Hz)")
    ap.add_argument("--order", type=int, default=32)
    ap.add_argument("--near", default="", help="approximate natural frequencies (Hz), comma-separated")
    a = ap.parse_args()
    t0 = time.perf_counter()
    try:
        import numpy as np
        import scipy
        import scipy.signal as sig
        from sdypy import EMA
        import importlib.metadata as md
    except ImportError as e:
        print(f"peer unavailable: {e} (pip install numpy scipy sdypy-EMA)", file=sys.stderr)
        sys.exit(2)
    stages = {"import": time.perf_counter() - t0}

    t = time.perf_counter()
    with open(a.recording) as f:
        names = f.readline().strip().lstrip("#").split(",")
    cols = [names.index(c) for c in ("time_s", "base_pos_m", "tip_pos_m")]
    d = np.loadtxt(a.recording, delimiter=",", skiprows=1, usecols=cols)
    time_s, base, tip = d[:, 0], d[:, 1], d[:, 2]
    del d
    stages["read"] = time.perf_counter() - t

    t = time.perf_counter()
    fs = 1.0 / np.median(np.diff(time_s[: min(time_s.size, 100000)]))
    if a.q > 1:
        base = sig.decimate(base, a.q, ftype="fir", zero_phase=True)
        tip = sig.decimate(tip, a.q, ftype="fir", zero_phase=True)
        fs /= a.q
    stages["decimate"] = time.perf_counter() - t

    t = time.perf_counter()
    x = np.zeros_like(base)
    x[1:-1] = (base[2:] - 2.0 * base[1:-1] + base[:-2]) * fs * fs
    y = tip - base
    n = x.size if a.nperseg <= 0 else min(a.nperseg, x.size)
    kw = dict(fs=fs, window=a.window, nperseg=n, noverlap=n // 2, detrend="constant")
    f, pxy = sig.csd(x, y, **kw)
    _, pxx = sig.welch(x, **kw)
    h1 = pxy / pxx
    stages["frf"] = time.perf_counter() - t

    t = time.perf_counter()
    lo, hi = (float(v) for v in a.band.split(","))
    sel = (f > 0) & (f <= 1.05 * hi)
    m = EMA.Model(frf=h1[sel][None, :], freq=f[sel], lower=lo, upper=hi,
                  pol_order_high=a.order, frf_type="receptance")
    m.get_poles(method="lscf", show_progress=False)
    near = [float(v) for v in a.near.split(",") if v.strip()]
    modes = []
    if near:
        m.select_closest_poles(near, f_window=1, fn_temp=0.01, xi_temp=0.05)
        modes = [[float(fn), float(z)] for fn, z in zip(m.nat_freq, m.nat_xi)]
    stages["lscf"] = time.perf_counter() - t

    print(json.dumps({
        "peer": "scipy.signal csd/welch H1 + sdypy-EMA LSCF",
        "versions": {"numpy": np.__version__, "scipy": scipy.__version__,
                     "sdypy-EMA": md.version("sdypy-EMA")},
        "samples": int(time_s.size), "fs_hz": float(fs), "nperseg": int(n),
        "stages_s": stages, "total_s": time.perf_counter() - t0,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "modes": modes,
    }))


if __name__ == "__main__":
    main()
