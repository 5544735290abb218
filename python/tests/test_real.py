"""The package on the real recordings of shared/data/real, and against the CLI on the same files."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

import beamshaper as bs
from conftest import DECAYS, STEEL_LVM


def cli_json(cli, args, tmp_path):
    out = tmp_path / "cli.json"
    r = subprocess.run([str(cli), *args, "--json", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return json.loads(out.read_text())


@pytest.mark.parametrize("name", ["50cm", "60cm"])
def test_cli_and_package_give_identical_numbers(real_dir, cli, tmp_path, name):
    path = DECAYS[name]
    cli_report = cli_json(cli, ["identify", str(path)], tmp_path)
    ours = bs.identify(bs.read_recording(path)).to_dict()
    assert ours == cli_report  # every number, path, reason and warning, bit for bit


def test_cli_and_package_identical_with_a_band(real_dir, cli, tmp_path):
    path = DECAYS["40cm"]
    cli_report = cli_json(cli, ["identify", str(path), "--f-min-hz", "2", "--f-max-hz", "30"], tmp_path)
    ours = bs.identify(bs.read_recording(path), f_min_hz=2, f_max_hz=30).to_dict()
    assert ours == cli_report


def test_cli_and_package_identical_on_a_magnitude_spectrum(cli, tmp_path):
    if not STEEL_LVM.exists():
        pytest.skip("real data not present")
    cli_report = cli_json(cli, ["identify", str(STEEL_LVM)], tmp_path)
    spec = bs.read_recording(STEEL_LVM)
    assert isinstance(spec, bs.Spectrum) and spec.kind == "magnitude"
    ident = bs.identify(spec)
    assert [m["freq_hz"] for m in cli_report] == [m.freq_hz for m in ident.modes]
    assert [m["zeta"] for m in cli_report] == [m.zeta for m in ident.modes]


@pytest.mark.parametrize("name,f1", [("40cm", 9.4065), ("50cm", 6.0545), ("60cm", 4.2588)])
def test_real_aluminium_decays(real_dir, name, f1):
    rec = bs.read_recording(DECAYS[name])
    assert isinstance(rec, bs.Recording) and rec.channels == ["tip_pos_m"]
    ident = bs.identify(rec)
    assert ident.path == "free decay"
    m1 = ident.modes[0]
    assert abs(m1.freq_hz - f1) < 1e-3 * f1
    assert 0 < m1.zeta < 0.05 and m1.freq_hz_std > 0 and m1.zeta_std > 0
    assert any("non-uniform time base" in w for w in ident.warnings)


def test_decay_to_shaper(real_dir):
    rec = bs.read_recording(DECAYS["50cm"])
    ident = bs.identify(rec)
    shaper = bs.design_shaper(ident, tolerance_pct=2.0)
    imp = shaper.impulses
    assert imp.shape == (len(imp), 2) and imp.dtype == np.float64
    assert imp[0, 0] == 0.0 and np.all(np.diff(imp[:, 0]) > 0)
    assert abs(imp[:, 1].sum() - 1.0) < 1e-12
    assert shaper.worst_pct <= 2.0 and shaper.duration_s == imp[-1, 0]
    for m in ident.modes:
        assert shaper.vibration_pct(m.freq_hz, m.zeta) <= 2.0
    assert all(r.duration_s >= shaper.duration_s for r in shaper.runners_up)
    # with the recording: the recorded free vibration must also stay within the tolerance
    checked = bs.design_shaper(ident, tolerance_pct=2.0, recording=rec)
    assert checked.duration_s >= shaper.duration_s


def klipper_raw_resonance_test(path, f_mode=42.0, zeta=0.06, rate=3200.0, seed=3):
    """A Klipper ``TEST_RESONANCES … OUTPUT=raw_data`` file: its sweep (acceleration 60·f mm/s²
    rising 20→80 Hz at 2 Hz/s) through one lightly damped toolhead mode, ADXL345 steps
    (38.3 mm/s²) and noise, ``#time,accel_x,accel_y,accel_z``."""
    from scipy import signal

    rng = np.random.default_rng(seed)
    t = np.arange(int(30.0 * rate)) / rate
    f = 20.0 + 2.0 * t
    drive = 60.0 * f * np.sin(2 * np.pi * (20.0 * t + t**2))
    wn = 2 * np.pi * f_mode
    b, a = signal.bilinear([2 * zeta * wn, wn**2], [1, 2 * zeta * wn, wn**2], fs=rate)
    x = signal.lfilter(b, a, drive) + rng.normal(0, 50.0, t.size)
    y = 0.1 * x + rng.normal(0, 50.0, t.size)
    z = rng.normal(0, 50.0, t.size)
    q = 38.3
    rows = np.column_stack([t + 100.0, *(np.round(v / q) * q for v in (x, y, z))])
    with open(path, "w") as fh:
        fh.write("#time,accel_x,accel_y,accel_z\n")
        np.savetxt(fh, rows, fmt=["%.6f", "%.2f", "%.2f", "%.2f"], delimiter=",")


def test_cli_and_package_identical_on_a_klipper_raw_file(cli, tmp_path):
    path = tmp_path / "raw_data_x_20261202.csv"
    klipper_raw_resonance_test(path)
    cli_report = cli_json(cli, ["identify", str(path)], tmp_path)
    rec = bs.read_recording(path)
    assert isinstance(rec, bs.Recording)
    ident = bs.identify(rec)
    assert ident.to_dict() == cli_report
    assert "Klipper PSD" in ident.path
    assert abs(ident.modes[0].freq_hz - 42.0) < 2.0
