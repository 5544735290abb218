#!/usr/bin/env python3
"""beamshaper.identify beside sdypy-EMA's LSCF (pip install sdypy-EMA) on the same arrays.

1. The three real aluminium cantilever decays (shared/data/real/aluminium-cantilever, plucked,
   ADXL357 near the tip, non-uniform time stamps): ``beamshaper.identify`` on the recording as
   read; sdypy-EMA LSCF (orders ≤ 32) on the spectrum of the same decay — the signal resampled
   to its median step, from its largest excursion on (the pluck taken as the impulse: the
   spectrum of the response is the FRF up to a constant), band 2–80 Hz — with the poles
   closest to beamshaper's frequencies (stability 1 % in f, 5 % in ζ; "none" when the closest
   stable pole is more than 5 % away).
2. Benchmark on one array and one band: the paper rig (rigs/paper.toml) under a 0.3–15 Hz
   exponential sweep of the base (120 s and 20 s of ring-down at the rig's 100 Hz, the
   README's accuracy case), simulated by ``beamshaper.simulate``, white noise of 5 % of each
   signal's RMS on the measured base and tip; the arrays time, base and tip (no command);
   ``beamshaper.identify(rec, band_hz=(0.3, 8))`` (the whole FRF path: H1,
   LSCF over orders, screening, ML refinement) against sdypy-EMA's FRF (H1 of the whole
   record, as beamshaper's default) + LSCF up to order 32 on 0.3–8 Hz, each the median of 7
   runs in this process; printed as the ratio.

Usage: python examples/compare_sdypy.py [--data DIR] [--repeat N]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import beamshaper as bs

REPO = Path(__file__).resolve().parents[2]
os.environ.setdefault("TQDM_DISABLE", "1")  # sdypy-EMA's progress bars


def sdypy_lscf(freq, frf, lo, hi, near, frf_type):
    from sdypy import EMA

    sel = (freq > 0) & (freq <= 1.05 * hi)
    m = EMA.Model(frf=frf[sel][None, :], freq=freq[sel], lower=lo, upper=hi,
                  pol_order_high=32, frf_form=frf_type)
    m.get_poles(method="lscf", show_progress=False)
    m.select_closest_poles(list(near), f_window=1, fn_temp=0.01, xi_temp=0.05)
    return list(zip(m.nat_freq, m.nat_xi))


def decay_spectrum(rec):
    d = rec.to_dict()
    t, x = d["time_s"], d["tip_pos_m"]
    dt = float(np.median(np.diff(t)))
    tu = np.arange(t[0], t[-1], dt)
    xu = np.interp(tu, t, x)
    xu = xu - xu.mean()
    k = int(np.argmax(np.abs(xu)))
    xu = xu[k:]
    return np.fft.rfftfreq(xu.size, dt), np.fft.rfft(xu) * dt


def real_decays(data: Path) -> None:
    files = sorted(data.glob("*.npy"))
    if not files:
        print(f"(no real data at {data}: part 1 skipped)")
        return
    print("1. real aluminium decays: beamshaper.identify vs sdypy-EMA LSCF (spectrum of the decay, 2-80 Hz)")
    print(f"   {'file':<10} {'mode':>4} {'beamshaper f (Hz)':>20} {'zeta':>18} {'sdypy f (Hz)':>13} {'zeta':>9}")
    for p in files:
        ident = bs.identify(bs.read_recording(p))
        modes = [m for m in ident.modes if 2.0 <= m.freq_hz <= 80.0]
        f, h = decay_spectrum(bs.read_recording(p))
        peer = sdypy_lscf(f, h, 2.0, 80.0, [m.freq_hz for m in modes], "accelerance")
        for i, m in enumerate(modes):
            pf, pz = peer[i] if i < len(peer) else (float("nan"), float("nan"))
            near = pf > 0 and abs(pf - m.freq_hz) <= 0.05 * m.freq_hz  # else: no stable pole near
            pf_s = f"{pf:13.4f}" if near else f"{'none':>13}"
            pz_s = f"{pz:9.5f}" if near else f"{'-':>9}"
            print(f"   {p.name[:8]:<10} {i + 1:>4} {m.freq_hz:>11.4f} ± {m.freq_hz_std:.4f} "
                  f"{m.zeta:>9.5f} ± {m.zeta_std:.5f} {pf_s} {pz_s}")


def sweep(rig, rate=100.0, seconds=120.0, tail=20.0, seed=1, noise=0.05):
    t = np.arange(int(rate * seconds)) / rate
    f0, f1 = 0.3, 15.0
    k = np.log(f1 / f0) / seconds
    fade = np.clip(np.minimum(t, seconds - t) / 2.0, 0, 1)
    y = 2e-3 * fade * np.sin(2 * np.pi * f0 * (np.exp(k * t) - 1) / k) / (1 + (f0 * np.exp(k * t)) ** 2 / 4)
    y = np.concatenate([y, np.zeros(int(tail * rate))])
    d = bs.simulate(rig, y, rate).to_dict()
    rng = np.random.default_rng(seed)
    for c in ("base_pos_m", "tip_pos_m"):
        d[c] = d[c] + rng.normal(0, noise * np.std(d[c]), d[c].size)
    return d


def h1_whole_record(x, y, dt):
    X = np.fft.rfft(x - x.mean())
    Y = np.fft.rfft(y - y.mean())
    return np.fft.rfftfreq(x.size, dt), Y * np.conj(X) / np.abs(X) ** 2


def benchmark(repeat: int) -> float:
    rig = bs.Rig.from_toml(REPO / "rigs" / "paper.toml")
    d = sweep(rig)
    band = (0.3, 8.0)
    print(f"2. benchmark: one simulated sweep of the paper rig ({d['time_s'].size} samples at 100 Hz, "
          f"5 % noise), band {band[0]}-{band[1]} Hz, median of {repeat} runs")

    def ours():
        rec = bs.Recording.from_arrays(d["time_s"], tip_pos_m=d["tip_pos_m"], base_pos_m=d["base_pos_m"])
        return bs.identify(rec, band_hz=band)

    def peer(near):
        dt = d["time_s"][1] - d["time_s"][0]
        b = d["base_pos_m"]
        x = np.zeros_like(b)
        x[1:-1] = (b[2:] - 2 * b[1:-1] + b[:-2]) / dt**2
        f, h = h1_whole_record(x, d["tip_pos_m"] - b, dt)
        return sdypy_lscf(f, h, band[0], band[1], near, "receptance")

    ident = ours()
    near = [m.freq_hz for m in ident.modes]
    peer(near)  # warm the imports
    t_ours, t_peer = [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        ident = ours()
        t_ours.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        modes = peer(near)
        t_peer.append(time.perf_counter() - t0)
    a, b = statistics.median(t_ours), statistics.median(t_peer)
    truth = [m["freq_hz_clamped_base"] for m in rig.modes(4)["modes"][:2]]
    print(f"   model (rig file): f = {truth[0]:.4f}, {truth[1]:.4f} Hz, zeta = 0.0074")
    for m in ident.modes:
        print(f"   beamshaper.identify: f = {m.freq_hz:.4f} ± {m.freq_hz_std:.4f} Hz, zeta = {m.zeta:.5f} ± {m.zeta_std:.5f}")
    for f, z in modes:
        print(f"   sdypy-EMA LSCF:      f = {f:.4f} Hz, zeta = {z:.5f}" if f > 0 else "   sdypy-EMA LSCF:      no stable pole")
    print(f"   time: beamshaper.identify {a * 1e3:.1f} ms, sdypy-EMA FRF + LSCF {b * 1e3:.1f} ms: "
          f"beamshaper is {b / a:.2f}x faster")
    return b / a


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data" / "real" / "aluminium-cantilever")
    ap.add_argument("--repeat", type=int, default=7)
    a = ap.parse_args()
    try:
        import sdypy.EMA  # noqa: F401
    except ImportError:
        print("needs sdypy-EMA: pip install sdypy-EMA", file=sys.stderr)
        return 2
    real_decays(a.data)
    benchmark(a.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
