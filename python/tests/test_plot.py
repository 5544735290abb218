"""beamshaper.plot draws with matplotlib, and says clearly when it is missing."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import beamshaper as bs
import beamshaper.plot as bsp

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")


def decay_recording():
    rate = 400.0
    t = np.arange(int(rate * 15)) / rate
    x = np.exp(-0.02 * 2 * np.pi * 5 * t) * np.cos(2 * np.pi * 5 * t) * 1e-3
    return bs.Recording.from_arrays(t, tip_pos_m=x)


def test_sensitivity_and_verification(tmp_path):
    rec = decay_recording()
    ident = bs.identify(rec)
    shaper = bs.design_shaper(ident)
    ax = bsp.sensitivity(shaper, modes=ident, tolerance_pct=2.0)
    ax.figure.savefig(tmp_path / "s.png")
    ax = bsp.verification(rec, shaper)
    assert "residual after" in ax.get_title()
    ax.figure.savefig(tmp_path / "v.png")
    assert (tmp_path / "s.png").stat().st_size > 1000
    t = rec.time_s
    x = rec.to_dict()["tip_pos_m"]
    y = bsp.shaped_by_superposition(t, x, shaper)
    after = t > shaper.duration_s + 0.1
    assert np.sqrt(np.mean(y[after] ** 2)) < 0.05 * np.sqrt(np.mean(x[after] ** 2))


def test_stabilisation_needs_the_frf_path():
    ident = bs.identify(decay_recording())
    with pytest.raises(ValueError, match="free decay"):
        bsp.stabilisation(ident)


def test_clear_import_error_without_matplotlib(monkeypatch):
    shaper = bs.design_shaper([(5.0, 0.01)])
    for name in list(sys.modules):
        if name == "matplotlib" or name.startswith("matplotlib."):
            monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(ImportError, match="pip install matplotlib"):
        bsp.sensitivity(shaper)
