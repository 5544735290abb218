"""Synthetic recordings: arrays in and out, the model, the engine."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

import beamshaper as bs
from conftest import PAPER_RIG


def decay(f_hz=3.0, zeta=0.01, rate=500.0, seconds=20.0):
    t = np.arange(int(rate * seconds)) / rate
    wd = 2 * np.pi * f_hz * np.sqrt(1 - zeta**2)
    x = 1e-3 * np.exp(-zeta * 2 * np.pi * f_hz * t) * np.cos(wd * t)
    x += np.random.default_rng(3).normal(0, 1e-7, t.size)
    return t, x


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_free_decay_from_arrays_any_dtype_and_strides(dtype):
    t, x = decay()
    # every other sample of a longer array: a non-contiguous view
    x2 = np.repeat(x.astype(dtype), 2)[::2]
    assert not x2.flags["C_CONTIGUOUS"]
    rec = bs.Recording.from_arrays(t, tip_pos_m=x2)
    assert len(rec) == t.size and rec.sample_rate_hz == pytest.approx(500.0)
    d = rec.to_dict()
    assert set(d) == {"time_s", "tip_pos_m"} and d["tip_pos_m"].dtype == np.float64
    np.testing.assert_array_equal(d["tip_pos_m"], x.astype(dtype).astype(np.float64))
    ident = bs.identify(rec)
    m = ident.modes[0]
    assert ident.path == "free decay"
    assert m.freq_hz == pytest.approx(3.0, rel=2e-3)
    assert m.zeta == pytest.approx(0.01, rel=0.1)
    assert m.to_dict()["freq_hz"] == m.freq_hz


def sweep_recording(rig, seconds=60.0, rate=200.0):
    """The paper rig under an exponential sweep 0.3-15 Hz of the base (m), simulated."""
    t = np.arange(int(rate * seconds)) / rate
    f0, f1 = 0.3, 15.0
    k = np.log(f1 / f0) / seconds
    phase = 2 * np.pi * f0 * (np.exp(k * t) - 1) / k
    fade = np.clip(np.minimum(t, seconds - t) / 2.0, 0, 1)
    y = 2e-3 * fade * np.sin(phase) / (1 + (f0 * np.exp(k * t)) ** 2 / 4)
    y = np.concatenate([y, np.zeros(int(5 * rate))])
    return bs.simulate(rig, y, rate), rate


def test_simulated_sweep_is_identified_on_the_frf_path():
    rig = bs.Rig.from_toml(PAPER_RIG)
    model = rig.modes(4)
    f_true = [m["freq_hz_clamped_base"] for m in model["modes"][:2]]
    rec, rate = sweep_recording(rig)
    d = rec.to_dict()
    assert set(d) == {"time_s", "base_cmd_m", "base_pos_m", "tip_pos_m", "force_n"}
    assert np.all(np.isfinite(d["tip_pos_m"]))
    ident = bs.identify(rec)
    assert ident.path.startswith("FRF")
    got = [m.freq_hz for m in ident.modes]
    for f in f_true:
        assert min(abs(g - f) / f for g in got) < 0.01, (got, f_true)
    st = ident.stabilisation()
    assert st is not None and st["freq_hz"].shape == st["h1_abs"].shape
    assert st["diagram"]["orders"]


def test_rig_modes_are_the_cli_table():
    rig = bs.Rig.from_toml(PAPER_RIG)
    m = rig.modes(6)
    assert len(m["modes"]) == 6 and m["beam_mass_kg"] > 0
    assert m["modes"][0]["freq_hz_clamped_base"] == pytest.approx(1.1047, rel=1e-3)
    same = bs.Rig.from_toml_str(PAPER_RIG.read_text()).modes(6)
    assert same == m


def test_apply_is_the_engine_with_unit_dc_gain():
    shaper = bs.design_shaper([(2.0, 0.02)], tolerance_pct=5.0)
    rate = 1000.0
    n = 3000
    step = np.where(np.arange(n) >= 100, 0.05, 0.0)
    y = shaper.apply(step, rate)
    assert y.dtype == np.float64 and y.shape == (n,)
    assert y[-1] == pytest.approx(0.05, abs=1e-9)  # unit DC gain to the count (1 nm)
    # y = Σ A_i x(t − t_i), an impulse between two ticks split linearly between them (the
    # engine's tap table), within its 1 nm counts
    k = np.arange(n, dtype=float)
    expect = sum(a_i * np.interp(k - t_i * rate, k, step, left=0.0) for t_i, a_i in shaper.impulses)
    assert np.max(np.abs(y - expect)) < 2e-9
    y32 = shaper.apply(step.astype(np.float32), rate, path="f32")
    assert np.max(np.abs(y32 - y)) < 1e-8
    const = shaper.apply(np.full(500, 0.0123), rate)
    assert np.all(np.abs(const - 0.0123) < 1e-9)


def test_vibration_pct_scalar_and_array():
    shaper = bs.design_shaper([bs.Mode(4.0, 0.01)], tolerance_pct=2.0)
    assert shaper.vibration_pct(4.0, 0.01) < 0.5
    f = np.linspace(1, 10, 50)
    v = shaper.vibration_pct(f, 0.01)
    assert v.shape == (50,) and v.dtype == np.float64
    assert v[0] == pytest.approx(shaper.vibration_pct(1.0, 0.01))


def test_simulate_then_shape_reduces_the_residual():
    rig = bs.Rig.from_toml(PAPER_RIG)
    rate = 1000.0
    t = np.arange(int(8 * rate)) / rate
    y = np.clip(t / 0.5, 0, 1) * 0.05  # a 0.5 s ramp to 50 mm
    modes = [(m["freq_hz_clamped_base"], m["damping_ratio"]) for m in rig.modes(4)["modes"][:2]]
    shaper = bs.design_shaper(modes, tolerance_pct=2.0)
    ys = shaper.apply(y, rate)
    tail = lambda r: np.ptp((r["tip_pos_m"] - r["base_pos_m"])[-3000:])
    un = tail(bs.simulate(rig, y, rate).to_dict())
    sh = tail(bs.simulate(rig, ys, rate).to_dict())
    assert sh < 0.1 * un, (sh, un)


def test_ctrl_c_interrupts_a_long_call(tmp_path):
    """diagnose runs for minutes; SIGINT (Ctrl-C) returns KeyboardInterrupt within seconds."""
    rig = bs.Rig.from_toml(PAPER_RIG)
    rate = 1000.0
    t = np.arange(8000) / rate
    y = np.where(t < 1.0, 0.025 * (1 - np.cos(np.pi * t)), 0.05)
    y = np.concatenate([np.zeros(500), y])
    r = bs.simulate(rig, y, rate).to_dict()
    cols = ["time_s", "base_cmd_m", "base_pos_m", "tip_pos_m", "force_n"]
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.column_stack([r[c] for c in cols]), delimiter=",", header=",".join(cols), comments="", fmt="%.9g")
    # Ctrl-C at a terminal: Python's own handler. A process started in the background of a
    # non-interactive shell inherits SIGINT ignored, and Python then installs none.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT))
    try:
        timer.start()
        t0 = time.perf_counter()
        with pytest.raises(KeyboardInterrupt):
            bs.diagnose(rig, [path], path)
        assert time.perf_counter() - t0 < 10.0
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)


def test_board_plan_refuses_what_the_board_cannot_run():
    modes = [(1.1, 0.0074, 0.001, 0.0005), (6.9, 0.0074, 0.01, 0.0005)]
    free = bs.design_shaper(modes)
    planned = bs.design_shaper(modes, move_mm=50.0)
    assert planned.duration_s >= free.duration_s
    with pytest.raises(ValueError, match="no shaper keeps"):
        bs.design_shaper(modes, move_mm=50.0, speed_mm_s=150.0, board={"max_step_rate_hz": 1000})
    with pytest.raises(ValueError, match="unknown setting"):
        bs.design_shaper(modes, move_mm=50.0, board={"ticks": 1})
