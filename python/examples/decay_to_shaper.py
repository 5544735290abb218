#!/usr/bin/env python3
"""From the real 50 cm aluminium cantilever decay to a shaper and its plots.

The recording (shared/data/real/aluminium-cantilever, an ADXL357 near the tip of a plucked
cantilever, ~20 s at ~4 kHz with logging gaps) is read as ``beamtool`` reads it, its modes are
identified (free-decay path), the shortest shaper whose worst-case percentage vibration over
the modes' uncertainty bands is ≤ 2 % is designed — checked also on the recorded vibration
itself (model-free, by superposition) — and the sensitivity curve and the verification are
drawn into OUT (default: a new temporary directory; never into the source tree).

Usage: python examples/decay_to_shaper.py [--data FILE.npy] [--out DIR]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

import beamshaper as bs

REPO = Path(__file__).resolve().parents[2]
DEFAULT = (REPO.parent / "shared" / "data" / "real" / "aluminium-cantilever"
           / "50cm_adxl_08-12_11-47-59_adxl6cmfromtip2cmID.npy")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", type=Path, default=DEFAULT)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    if not a.data.exists():
        print(f"no recording at {a.data} (the shared real data): nothing to do", file=sys.stderr)
        return 0
    out = a.out or Path(tempfile.mkdtemp(prefix="beamshaper-example-"))
    out.mkdir(parents=True, exist_ok=True)

    rec = bs.read_recording(a.data)
    assert isinstance(rec, bs.Recording), "a time recording (.npy or CSV), not a spectrum"
    print(rec)
    ident = bs.identify(rec)
    print(f"path: {ident.path} ({ident.reason})")
    for m in ident.modes:
        print(f"  f = {m.freq_hz:.4f} ± {m.freq_hz_std:.4f} Hz, zeta = {m.zeta:.5f} ± {m.zeta_std:.5f} ({m.method})")
    for w in ident.warnings:
        print(f"  warning: {w}")

    shaper = bs.design_shaper(ident, tolerance_pct=2.0, recording=rec)
    print(f"shaper: {shaper.name}: {len(shaper.impulses)} impulses, {shaper.duration_s * 1e3:.1f} ms, "
          f"worst case {shaper.worst_pct:.2f} % over the bands")
    print("  time_s       amplitude")
    for t, amp in shaper.impulses:
        print(f"  {t:.6f}  {amp:+.6f}")
    for r in shaper.runners_up[:3]:
        print(f"  runner-up: {r.name} ({r.duration_s * 1e3:.1f} ms, {r.worst_pct:.2f} %)")
    for m in ident.modes:
        print(f"  V at mode {m.freq_hz:.3f} Hz: {shaper.vibration_pct(m.freq_hz, m.zeta):.4f} %")

    # the firmware core's engine on a 10 mm step at 1 kHz: unit DC gain
    step = np.where(np.arange(1000) >= 10, 0.01, 0.0)
    shaped = shaper.apply(step, 1000.0)
    print(f"engine: a 10 mm step at 1 kHz ends at {shaped[-1] * 1e3:.6f} mm")

    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from beamshaper import plot
    except ImportError:
        print("matplotlib not installed: no plots (pip install matplotlib)")
        return 0
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 7))
    plot.sensitivity(shaper, ax=ax1, modes=ident, tolerance_pct=2.0, f_max_hz=60.0)
    plot.verification(rec, shaper, ax=ax2)
    ax2.set_xlim(0, 3)
    fig.tight_layout()
    for ext in ("svg", "png"):
        fig.savefig(out / f"decay_to_shaper.{ext}")
    print(f"plots -> {out}/decay_to_shaper.svg, .png ({ax2.get_title()})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
