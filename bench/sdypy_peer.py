#!/usr/bin/env python3
"""Peer comparison: sdypy-EMA's LSCF against `beamtool identify` on the same recording.

Usage (from tools/):
    python3 ../bench/sdypy_peer.py REC_CLEAN.csv --noise 0.05 --seeds 1-10 --truth 1.1047,6.9228 \
        --beamtool /path/to/beamtool

Adds white Gaussian noise of NOISE x RMS to base_pos_m, tip_pos_m and force_n (the definition
of tools/src/ident/protocol.rs; base_cmd_m stays clean) for each seed, writes
REC_CLEAN-noisy<seed>.csv, then
  1. sdypy-EMA (pip install sdypy-EMA): FRF H1 = Y X*/|X|^2 of the whole record (rectangular
     window, one segment, as beamtool's default) with X = base acceleration (second difference
     of base_pos_m) and Y = tip deflection (tip_pos_m - base_pos_m), band 0.3-8 Hz, LSCF poles
     up to order 32 (`get_poles('lscf')`), `select_closest_poles(truth)`;
     the same with the clean command as input (X = its second difference, Y = tip - command),
     so that the estimator is compared on the input beamtool cleans its base from;
  2. `beamtool identify` on the noisy CSV (its default; --band 0.3,8 --modes 2).
Prints each seed and a summary: error mean +- sd, seeds meeting the target, median run time.
Not a dependency of the tools: a script beside the benchmarks.
"""
import argparse, csv, json, subprocess, time
import numpy as np


def load(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0].keys()}


def h1_whole_record(x, y, dt):
    """H1 of the whole record (rectangular window, one segment): Y X* / |X|^2."""
    X = np.fft.rfft(x - x.mean())
    Y = np.fft.rfft(y - y.mean())
    return np.fft.rfftfreq(x.size, dt), Y * np.conj(X) / np.abs(X) ** 2


def accel(b, dt):
    x = np.zeros_like(b)
    x[1:-1] = (b[2:] - 2 * b[1:-1] + b[:-2]) / dt**2
    return x


def sdypy_lscf(f, H, truth):
    """sdypy-EMA LSCF up to order 32 on 0.3-8 Hz; poles closest to the truth with its default
    stability criteria (0.1 % in f, 5 % in zeta) and relaxed ones (1 % in f, 5 % in zeta);
    0 = no stable pole found near the truth."""
    from sdypy import EMA
    sel = f <= 10.0
    m = EMA.Model(frf=H[sel][None, :], freq=f[sel], lower=0.3, upper=8.0, pol_order_high=32, frf_type="receptance")
    m.get_poles(method="lscf", show_progress=False)
    m.select_closest_poles(truth, f_window=1)
    default = (list(m.nat_freq), list(m.nat_xi))
    m.select_closest_poles(truth, f_window=1, fn_temp=0.01, xi_temp=0.05)
    return default, (list(m.nat_freq), list(m.nat_xi))


def add_noise(d, frac, seed):
    rng = np.random.default_rng(seed)
    out = dict(d)
    for c in ("base_pos_m", "tip_pos_m", "force_n"):
        if c in d:
            v = d[c]
            out[c] = v + rng.normal(0.0, frac * np.sqrt(np.mean((v - v.mean()) ** 2)), v.size)
    return out


def write(path, d):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        keys = list(d.keys())
        w.writerow(keys)
        for i in range(d["time_s"].size):
            w.writerow([repr(float(d[k][i])) for k in keys])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("recording")
    ap.add_argument("--noise", type=float, default=0.05)
    ap.add_argument("--seeds", default="1-10", help="e.g. 1-10 or 3,5")
    ap.add_argument("--truth", default="1.1047,6.9228", help="f1,f2 (Hz)")
    ap.add_argument("--zeta", default="0.0074,0.0074", help="zeta1,zeta2 truth")
    ap.add_argument("--beamtool", default="beamtool")
    a = ap.parse_args()
    d = load(a.recording)
    truth = [float(x) for x in a.truth.split(",")]
    zt = [float(x) for x in a.zeta.split(",")]
    if "-" in a.seeds:
        lo, hi = (int(x) for x in a.seeds.split("-"))
        seeds = list(range(lo, hi + 1))
    else:
        seeds = [int(x) for x in a.seeds.split(",")]
    rows = {k: [] for k in ["sdypy-EMA LSCF, measured base", "  same, relaxed 1 % criterion", "sdypy-EMA LSCF, command input", "  same, relaxed 1 % criterion ", "beamtool identify"]}
    times = {k: [] for k in rows}
    relaxed = {"measured base": "  same, relaxed 1 % criterion", "command input": "  same, relaxed 1 % criterion "}
    dt = d["time_s"][1] - d["time_s"][0]
    for seed in seeds:
        n = add_noise(d, a.noise, seed)
        noisy = a.recording.replace(".csv", f"-noisy{seed}.csv")
        write(noisy, n)
        for col, label in (("base_pos_m", "measured base"), ("base_cmd_m", "command input")):
            if col not in n:
                continue
            t0 = time.perf_counter()
            b = n[col]
            f, H = h1_whole_record(accel(b, dt), n["tip_pos_m"] - b, dt)
            r0, r1 = sdypy_lscf(f, H, truth)
            rows[f"sdypy-EMA LSCF, {label}"].append(r0)
            rows[relaxed[label]].append(r1)
            times[f"sdypy-EMA LSCF, {label}"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        out = subprocess.run([a.beamtool, "identify", noisy, "--band", "0.3,8", "--modes", "2", "--json", noisy + ".json"], capture_output=True, text=True)
        times["beamtool identify"].append(time.perf_counter() - t0)
        if out.returncode != 0:
            raise SystemExit(out.stderr)
        ours = json.load(open(noisy + ".json"))["modes"]
        rows["beamtool identify"].append(([m["freq_hz"] for m in ours[:2]], [m["zeta"] for m in ours[:2]]))
        print(f"seed {seed}: " + "; ".join(f"{k.strip()}: f {np.round(v[-1][0], 4)} zeta {np.round(v[-1][1], 5)}" for k, v in rows.items() if v), flush=True)

    print(f"\n{len(seeds)} seeds, {100 * a.noise:.0f} % noise on base_pos_m, tip_pos_m (base_cmd_m clean)")
    print("errors in %: mean +- sd [found/seeds] over the seeds where a stable pole was found near the truth;")
    print("last column: seeds with all four within the target (f 0.2 %, zeta 15 %)")
    print(f"{'tool':32} {'f1':>22} {'f2':>22} {'zeta1':>22} {'zeta2':>22} {'in target':>10} {'time (s)':>9}")
    for k, v in rows.items():
        if not v:
            continue
        errs = [[], [], [], []]
        ok = 0
        for fr, ze in v:
            e = [None] * 4
            for i in range(2):
                # sdypy returns 0 for a mode it did not find and does not keep the truth's order:
                # match each truth mode to the returned pole nearest in frequency (within 3 %).
                cands = [(abs(f / truth[i] - 1), f, z) for f, z in zip(fr, ze) if f > 0]
                cands = [c for c in cands if c[0] < 0.03]
                if cands:
                    _, f, z = min(cands)
                    e[i] = 100 * (f / truth[i] - 1)
                    e[2 + i] = 100 * (z / zt[i] - 1)
            for i in range(4):
                if e[i] is not None:
                    errs[i].append(e[i])
            ok += all(x is not None for x in e) and abs(e[0]) < 0.2 and abs(e[1]) < 0.2 and abs(e[2]) < 15 and abs(e[3]) < 15
        cell = lambda x: (f"{np.mean(x):+.3f}+-{np.std(x, ddof=1) if len(x) > 1 else 0:.3f} [{len(x)}]") if x else f"- [0]"
        t = f"{np.median(times[k]):9.3f}" if k in times and times[k] else ""
        print(f"{k:32} {cell(errs[0]):>22} {cell(errs[1]):>22} {cell(errs[2]):>22} {cell(errs[3]):>22} {ok:>7}/{len(v):<2} {t}")
    print("time: median wall-clock per seed (sdypy: FRF + LSCF in-process; beamtool: whole CLI process incl. CSV parsing)")


if __name__ == "__main__":
    main()
