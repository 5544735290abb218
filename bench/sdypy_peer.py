#!/usr/bin/env python3
"""Peer comparison: sdypy-EMA's LSCF against `beamtool identify` on the same recording.

Usage (from tools/):
    python3 ../bench/sdypy_peer.py REC_CLEAN.csv --noise 0.05 --seed 1 --truth 1.1047,6.9228 \
        --beamtool /path/to/beamtool

Adds white Gaussian noise of NOISE x RMS to base_pos_m, tip_pos_m and force_n (the definition
of tools/src/ident/protocol.rs), writes REC_CLEAN-noisy.csv, then
  1. sdypy-EMA (pip install sdypy-EMA): FRF H1 = Y X*/|X|^2 of the whole record (rectangular
     window, one segment, as beamtool's default) with X = base acceleration (second difference
     of base_pos_m) and Y = tip deflection (tip_pos_m - base_pos_m), band 0.3-8 Hz, LSCF poles
     up to order 32 (`get_poles('lscf')`), `select_closest_poles(truth)`;
  2. `beamtool identify` on the noisy CSV (LSCF, its default; --band 0.3,8 --modes 2).
Prints both with their wall-clock run times.
Not a dependency of the tools: a script beside the benchmarks.
"""
import argparse, csv, json, subprocess, time
import numpy as np


def load(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0].keys()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("recording")
    ap.add_argument("--noise", type=float, default=0.05)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--truth", default="1.1047,6.9228")
    ap.add_argument("--beamtool", default="beamtool")
    a = ap.parse_args()
    d = load(a.recording)
    rng = np.random.default_rng(a.seed)
    for c in ("base_pos_m", "tip_pos_m", "force_n"):
        if c in d:
            v = d[c]
            d[c] = v + rng.normal(0.0, a.noise * np.sqrt(np.mean((v - v.mean()) ** 2)), v.size)
    noisy = a.recording.replace(".csv", "-noisy.csv")
    with open(noisy, "w", newline="") as f:
        w = csv.writer(f)
        keys = list(d.keys())
        w.writerow(keys)
        for i in range(d["time_s"].size):
            w.writerow([repr(float(d[k][i])) for k in keys])
    truth = [float(x) for x in a.truth.split(",")]

    t0 = time.perf_counter()
    from sdypy import EMA
    dt = d["time_s"][1] - d["time_s"][0]
    b = d["base_pos_m"]
    x = np.zeros_like(b)
    x[1:-1] = (b[2:] - 2 * b[1:-1] + b[:-2]) / dt**2
    y = d["tip_pos_m"] - b
    X = np.fft.rfft(x - x.mean())
    Y = np.fft.rfft(y - y.mean())
    f = np.fft.rfftfreq(x.size, dt)
    H = Y * np.conj(X) / np.abs(X) ** 2
    sel = f <= 10.0
    m = EMA.Model(frf=H[sel][None, :], freq=f[sel], lower=0.3, upper=8.0, pol_order_high=32, frf_type="receptance")
    m.get_poles(method="lscf", show_progress=False)
    # sdypy's default stability criteria (0.1 % in f, 5 % in zeta); f_window suits an 8 Hz band.
    m.select_closest_poles(truth, f_window=1)
    t_sdypy = time.perf_counter() - t0
    f_def, z_def = list(m.nat_freq), list(m.nat_xi)
    m.select_closest_poles(truth, f_window=1, fn_temp=0.01, xi_temp=0.05)
    f_rel, z_rel = list(m.nat_freq), list(m.nat_xi)

    t0 = time.perf_counter()
    out = subprocess.run([a.beamtool, "identify", noisy, "--band", "0.3,8", "--modes", "2", "--json", noisy + ".json"], capture_output=True, text=True)
    t_ours = time.perf_counter() - t0
    if out.returncode != 0:
        raise SystemExit(out.stderr)
    ours = json.load(open(noisy + ".json"))["modes"]

    print(f"{'':24} {'f1 (Hz)':>10} {'f2 (Hz)':>10} {'zeta1':>9} {'zeta2':>9} {'time (s)':>9}")
    print(f"{'truth':24} {truth[0]:10.4f} {truth[1]:10.4f} {0.0074:9.5f} {0.0074:9.5f}")
    print("(0 = no stable pole found near the truth)")
    print(f"{'sdypy-EMA LSCF':24} {f_def[0]:10.4f} {f_def[1]:10.4f} {z_def[0]:9.5f} {z_def[1]:9.5f} {t_sdypy:9.3f}")
    print(f"{'sdypy-EMA LSCF, 1 % in f':24} {f_rel[0]:10.4f} {f_rel[1]:10.4f} {z_rel[0]:9.5f} {z_rel[1]:9.5f}")
    print(f"{'beamtool identify (LSCF)':24} {ours[0]['freq_hz']:10.4f} {ours[1]['freq_hz']:10.4f} {ours[0]['zeta']:9.5f} {ours[1]['zeta']:9.5f} {t_ours:9.3f}")


if __name__ == "__main__":
    main()
