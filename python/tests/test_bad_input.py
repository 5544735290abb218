"""Bad input gives ValueError / OSError with the CLI's messages, never a PanicException."""

from __future__ import annotations

import numpy as np
import pytest

import beamshaper as bs
from conftest import PAPER_RIG

T = np.arange(1000) / 100.0
X = np.sin(2 * np.pi * T)


def test_nan_in_a_channel():
    x = X.copy()
    x[17] = np.nan
    with pytest.raises(ValueError, match=r"tip_pos_m is not finite .* row 18"):
        bs.Recording.from_arrays(T, tip_pos_m=x)


def test_nan_in_time():
    t = T.copy()
    t[3] = np.nan
    with pytest.raises(ValueError, match="time_s is not finite"):
        bs.Recording.from_arrays(t, tip_pos_m=X)


def test_empty():
    with pytest.raises(ValueError, match="0 samples"):
        bs.Recording.from_arrays(np.array([]), tip_pos_m=np.array([]))


def test_wrong_shapes():
    with pytest.raises(ValueError, match="1-D"):
        bs.Recording.from_arrays(np.stack([T, T]), tip_pos_m=X)
    with pytest.raises(ValueError, match="1-D"):
        bs.Recording.from_arrays(T, tip_pos_m=X[:, None])
    with pytest.raises(ValueError, match="999 samples, time_s has 1000"):
        bs.Recording.from_arrays(T, tip_pos_m=X[:-1])


def test_non_monotonic_time():
    t = T.copy()
    t[500] = t[498]
    with pytest.raises(ValueError, match="not strictly increasing at data row 501"):
        bs.Recording.from_arrays(t, tip_pos_m=X)


def test_no_channel_and_not_numbers():
    with pytest.raises(ValueError, match="at least one channel"):
        bs.Recording.from_arrays(T)
    with pytest.raises(ValueError, match="time_s"):
        bs.Recording.from_arrays(["a", "b"], tip_pos_m=[1.0, 2.0])


def test_missing_file_is_oserror(tmp_path):
    with pytest.raises(OSError):
        bs.read_recording(tmp_path / "nope.csv")
    with pytest.raises(OSError):
        bs.read_recording(tmp_path / "nope.npy")
    with pytest.raises(OSError):
        bs.Rig.from_toml(tmp_path / "nope.toml")


def test_bad_cells_and_options(tmp_path):
    p = tmp_path / "rec.csv"
    p.write_text("time_s,tip_pos_m\n0,0\n0.01,x\n0.02,0\n")
    with pytest.raises(ValueError, match="not a number"):
        bs.read_recording(p)
    p.write_text("t,defl\n" + "".join(f"{k * 10},{np.sin(k / 5):.6f}\n" for k in range(300)))
    with pytest.raises(ValueError, match="unknown channel"):
        bs.read_recording(p, columns="tip=defl")
    with pytest.raises(ValueError, match="--axis"):
        bs.read_recording(p, axis="w")
    rec = bs.read_recording(p, columns={"time_s": ("t", 0.001), "tip_pos_m": "defl"})
    assert len(rec) == 300 and rec.channels == ["tip_pos_m"]
    assert rec.to_dict()["time_s"][1] == pytest.approx(0.01)


def test_identify_refuses():
    rec = bs.Recording.from_arrays(T[:40], tip_pos_m=X[:40])
    with pytest.raises(ValueError, match="at least 64"):
        bs.identify(rec)
    rec = bs.Recording.from_arrays(T, tip_pos_m=X)
    with pytest.raises(ValueError, match="f_max_hz"):
        bs.identify(rec, f_min_hz=5, f_max_hz=1)
    with pytest.raises(ValueError, match="identification path"):
        bs.identify(rec, path="sideways")
    with pytest.raises(ValueError, match="Recording or a Spectrum"):
        bs.identify([1, 2, 3])


def test_design_refuses():
    with pytest.raises(ValueError, match="empty"):
        bs.design_shaper([])
    with pytest.raises(ValueError, match="tolerance_pct"):
        bs.design_shaper([(6.0, 0.01)], tolerance_pct=0.0)
    with pytest.raises(ValueError, match="zeta"):
        bs.design_shaper([(6.0, 1.5)])
    with pytest.raises(ValueError, match="freq_hz"):
        bs.design_shaper([(-1.0, 0.01)])
    with pytest.raises(ValueError, match="no shaper keeps"):
        bs.design_shaper([(6.0, 0.01, 3.0, 0.0)], tolerance_pct=0.2)


def test_apply_and_simulate_refuse():
    s = bs.design_shaper([(5.0, 0.01)])
    with pytest.raises(ValueError, match="not finite"):
        s.apply(np.array([0.0, np.nan]), 1000.0)
    with pytest.raises(ValueError, match="empty"):
        s.apply(np.array([]), 1000.0)
    with pytest.raises(ValueError, match="rate_hz"):
        s.apply(np.zeros(10), 0.0)
    with pytest.raises(ValueError, match="1 m"):
        s.apply(np.full(10, 3.0), 1000.0)
    with pytest.raises(ValueError, match="freq_hz"):
        s.vibration_pct(np.array([1.0, -2.0]), 0.01)
    rig = bs.Rig.from_toml(PAPER_RIG)
    with pytest.raises(ValueError, match="empty"):
        bs.simulate(rig, np.array([]), 1000.0)
    with pytest.raises(ValueError, match="1-D"):
        bs.simulate(rig, np.zeros((3, 3)), 1000.0)
    with pytest.raises(ValueError, match="n_modes"):
        rig.modes(0)


def test_diagnose_refuses(tmp_path):
    rig = bs.Rig.from_toml(PAPER_RIG)
    with pytest.raises(ValueError, match="at least one"):
        bs.diagnose(rig, [], tmp_path / "v.csv")
    with pytest.raises(OSError):
        bs.diagnose(rig, [tmp_path / "f.csv"], tmp_path / "v.csv")
    # a logger's file without a map is refused by its time column; a bad map by its channel
    f = tmp_path / "logger.csv"
    f.write_text("t,pos,tip\n" + "".join(f"{10 * k},{0.001 * k},0\n" for k in range(50)))
    with pytest.raises(ValueError, match="time column `t` has no unit"):
        bs.diagnose(rig, [f], f)
    with pytest.raises(ValueError, match="unknown channel `tip`"):
        bs.diagnose(rig, [f], f, columns="tip=tip")
    with pytest.raises(ValueError, match="column `nope`"):
        bs.diagnose(rig, [f], f, columns={"time_s": ("t", 0.001), "tip_pos_m": "nope"})
