"""beamshaper: modal identification, input-shaper design, simulation and diagnosis of flexible
beams on a moving base, from Python.

The functions run the project's Rust host-tools library (``beamtools``) and the firmware core
(``beamshaper``) in-process: no subprocess, no files in between. Arrays are numpy arrays of one
axis in SI units (s, m, N, m/s²); float64 or float32, any strides. Errors are Python exceptions
with the command-line tool's messages: ``ValueError`` for bad input (NaN, empty, wrong shapes,
non-increasing time, nothing identifiable, …) and ``OSError`` for files that cannot be read.
Long calls release the GIL; Ctrl-C interrupts them (``KeyboardInterrupt``) at the library's
next progress report.

Five lines from a recording to a shaper::

    import beamshaper as bs
    rec = bs.read_recording("decay.npy")
    ident = bs.identify(rec, f_max_hz=50)
    shaper = bs.design_shaper(ident, tolerance_pct=2.0)
    print(shaper.name, shaper.impulses)

``beamshaper.plot`` draws the sensitivity curve, the stabilisation diagram and the
verification (matplotlib, optional).
"""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

from . import _beamshaper
from ._beamshaper import Identification, Mode, Recording, Rig, Shaper, Spectrum

__version__: str = _beamshaper.__version__

__all__ = [
    "Identification",
    "Mode",
    "Recording",
    "Rig",
    "Shaper",
    "Spectrum",
    "read_recording",
    "identify",
    "design_shaper",
    "simulate",
    "diagnose",
]

PathLike = Union[str, "os.PathLike[str]"]


def read_recording(
    path: PathLike,
    columns: Optional[Union[str, Dict[str, Union[str, Tuple[str, float]]]]] = None,
    axis: Optional[str] = None,
) -> Union[Recording, Spectrum]:
    """Read a recording or spectrum file, every format ``beamtool`` reads.

    Formats (by content and extension; docs/recording-formats.md has each with an example):

    - the project's CSV (``time_s`` and any of ``base_cmd_m``, ``base_pos_m``, ``tip_pos_m``,
      ``force_n``, ``tip_acc_m_s2``; ``;``/tab separated, ``_mm``/``_um``/``time_ms`` columns
      converted to SI with a note), any CSV through ``columns``, Klipper's raw accelerometer
      CSV (``#time,accel_x,accel_y,accel_z``, one axis as ``tip_acc_m_s2``), row-wise logs
      (forward-filled) → :class:`Recording`, gaps and jitter kept (``identify`` splits at gaps);
    - NumPy ``.npy`` of shape (2, N) = [time_s; signal] → :class:`Recording` with the signal as
      ``tip_pos_m`` in the unit it was recorded in (a note says so);
    - LabVIEW ``.lvm`` magnitude spectrum (frequency Hz, dB) → :class:`Spectrum` (kind
      ``"magnitude"``); Klipper's ``resonances_*.csv`` / ``calibration_data_*.csv`` PSD →
      :class:`Spectrum` (kind ``"klipper_psd"``).

    Args:
        path: the file.
        columns: the CLI's ``--columns``: which file column holds which channel, with its scale
            to SI, as ``"channel=column[:scale],…"`` (e.g. ``"time_s=t:0.001,tip_pos_m=defl:0.001"``)
            or a dict ``{"tip_pos_m": ("defl", 0.001), "time_s": "t"}``.
        axis: the CLI's ``--axis``: ``"x"``, ``"y"`` or ``"z"`` of a Klipper raw accelerometer
            file (default: the axis with the most energy).

    Returns:
        A :class:`Recording` (``.notes`` says what reading noted or mended) or a
        :class:`Spectrum`.

    Raises:
        OSError: the file cannot be opened or read.
        ValueError: the file's content (a cell that is not a number, with its row and column;
            no time column; time going backwards; ``columns`` naming an unknown channel or a
            column the file does not have; ``columns``/``axis`` on a ``.npy``).
    """
    return _beamshaper.read_recording(os.fspath(path), columns, axis)


def identify(
    recording: Union[Recording, Spectrum],
    f_min_hz: Optional[float] = None,
    f_max_hz: Optional[float] = None,
    path: str = "auto",
    method: str = "lscf",
    band_hz: Optional[Tuple[float, float]] = None,
    n_modes: Optional[int] = None,
) -> Identification:
    """Identify the modes of a recording: ``beamtool identify``, same code, same numbers.

    The path is chosen from the recording and reported (``Identification.path`` and
    ``.reason``): a base that oscillates → FRF path (Welch H1 of base acceleration → tip
    deflection, LSCF stabilised over model orders, maximum-likelihood refinement; paper §5.2,
    Peeters et al. 2004 for LSCF); no input channel or a still base → free decay of the tip
    (peak-picked spectrum, damped-sinusoid fits and the log decrement, paper eqs. 28–29);
    moves followed by ≥ 3 s of stillness → ring-down after the last move. Only physical modes
    are kept (stable over orders, a peak ≥ 13 dB over the noise, a plausible ζ); the others are
    in ``.rejected`` with the reason. A ``.lvm`` magnitude spectrum: at most 6 peaks ≥ 10 dB
    prominent, single-mode accelerance fits.

    Args:
        recording: a :class:`Recording` (N ≥ 64 samples after the longest clean stretch) or a
            magnitude :class:`Spectrum` (``.lvm``).
        f_min_hz, f_max_hz: band considered by the free-decay and spectrum paths (Hz; the
            CLI's ``--f-min-hz``/``--f-max-hz``, defaults 0.2 and 500).
        path: ``"auto"``, ``"frf"``, ``"decay"`` or ``"output-only"`` (the CLI's ``--path``).
        method: FRF estimators, comma-separated, first is primary: ``lscf``, ``lsce``,
            ``peak``, ``logdec``, ``all`` (the CLI's ``--method``).
        band_hz: FRF band (Hz) ``(f_lo, f_hi)``; default where the input has energy.
        n_modes: keep the N best-supported modes.

    Returns:
        :class:`Identification`: ``.modes`` (ascending :class:`Mode`: ``freq_hz`` Hz, ``zeta``,
        ``freq_hz_std``, ``zeta_std`` 1-σ, ``method``), ``.path``, ``.reason``, ``.warnings``,
        ``.rejected``, ``.rayleigh`` (α1 1/s, α2 s; eq. 22), ``.to_dict()`` (the CLI's JSON).

    Raises:
        ValueError: invalid recording (NaN, non-increasing time, a time base in ms), too short,
            bad options, no physical mode found on the path taken (the message names the path
            and why), a Klipper PSD (no phase: use :func:`design_shaper`).
        OSError: the ``.lvm`` file of a spectrum cannot be read.
        KeyboardInterrupt: Ctrl-C.
    """
    return _beamshaper.identify(recording, f_min_hz, f_max_hz, path, method, band_hz, n_modes)


def design_shaper(
    modes: Union[Identification, Spectrum, Sequence[Union[Mode, Tuple[float, ...]]]],
    tolerance_pct: float = 2.0,
    min_band_pct: float = 2.0,
    recording: Optional[Recording] = None,
    signal: Optional[str] = None,
    move_mm: Optional[float] = None,
    speed_mm_s: float = 150.0,
    accel_mm_s2: float = 2000.0,
    board: Optional[Dict[str, int]] = None,
) -> Shaper:
    """Design the shortest robust input shaper: ``beamtool tune``'s design step.

    Every shaper kind of the firmware core (ZV, ZVD, ZVDD, EI, 2-hump EI, …) for mode 1, and
    for modes 1 + 2 by convolution (paper §4), is scored by its worst-case percentage
    vibration V (paper eq. 27) over the uncertainty band of every mode: f ∈ f̂·[1 − b, 1 + b]
    with b = max(2σ_f/f̂, ``min_band_pct``/100), ζ ∈ [ζ̂ − 2σ_ζ, ζ̂ + 2σ_ζ]. The shortest
    candidate within ``tolerance_pct`` wins; with ``recording`` it must also leave the
    recorded free vibration within the tolerance (model-free, by superposition); with
    ``move_mm`` the board (the firmware's default settings, with ``board``'s entries) must be
    able to run a move of that length with it (the step-rate rule with the shaper's
    amplitudes, the capture length), planned as ``beamtool tune`` plans its verification move.

    A Klipper PSD :class:`Spectrum` is designed for instead by ``beamtool tune``'s spectrum
    path: the least smoothing within Klipper's remaining-vibrations budget; Klipper's own
    recommendation is the runner-up.

    Args:
        modes: an :class:`Identification`, a list of :class:`Mode`, of ``(freq_hz, zeta)`` or
            ``(freq_hz, zeta, freq_hz_std, zeta_std)`` tuples (Hz, fraction), or a Klipper PSD
            :class:`Spectrum`.
        tolerance_pct: worst-case V allowed (%), 0.2 … 50.
        min_band_pct: minimum half-width of the checked frequency band (% of f), 0 … 50.
        recording: a recording holding a free vibration of the tip after the base's last move.
        signal: what the recording's tip signal is: ``"position"`` or ``"acceleration"``
            (integrated twice); default acceleration for a ``.npy`` file or a recording with
            only ``tip_acc_m_s2``, else position.
        move_mm, speed_mm_s, accel_mm_s2: the verification move the board must be able to run
            (mm, mm/s, mm/s²); without ``move_mm`` no board plan is checked.
        board: the board's settings for that plan, overriding the firmware's defaults:
            ``{"tick_rate_hz": …, "step_nm": …, "max_step_rate_hz": …}`` (integers).

    Returns:
        :class:`Shaper`: ``.name``, ``.impulses`` (n, 2) [time_s, amplitude], ``.duration_s``,
        ``.worst_pct``, ``.runners_up`` (≤ 5 feasible, by duration), ``.vibration_pct(f, ζ)``,
        ``.apply(signal, rate_hz)``.

    Raises:
        ValueError: no mode, bad numbers, board settings the firmware refuses, no shaper meets
            the tolerance and runs on the board (the message gives the first three reasons), a
            recording without free vibration.
    """
    return _beamshaper.design_shaper(
        modes, tolerance_pct, min_band_pct, recording, signal, move_mm, speed_mm_s, accel_mm_s2, board
    )


def simulate(rig: Rig, base_cmd_m: Any, rate_hz: float, n_modes: int = 4) -> Recording:
    """Simulate the beam of ``rig`` under a base position command (paper §2).

    The Galerkin model of the clamped–free beam on its base (eqs. 10–22, ``n_modes`` basis
    functions, Rayleigh damping from the rig file) is integrated exactly mode by mode
    (zero-order hold of the base velocity between samples), the base following the command
    ideally; the same simulator as ``beamtool simulate``, run at ``rate_hz`` (the CLI runs at
    1 kHz and decimates to the rig's sensor rate).

    Args:
        rig: the :class:`Rig`.
        base_cmd_m: base position command (m), shape (N,), N ≥ 2, uniform at ``rate_hz``;
            the beam is at rest before the first sample.
        rate_hz: sample rate of the command (Hz).
        n_modes: basis functions of the model (1 … 20).

    Returns:
        :class:`Recording` of N samples: ``time_s``, ``base_cmd_m`` = ``base_pos_m`` (m),
        ``tip_pos_m`` (absolute, m), ``force_n`` (base force, N).

    Raises:
        ValueError: empty, NaN or not 1-D command; ``rate_hz`` ≤ 0; a rig the model refuses.
    """
    return _beamshaper.simulate(rig, base_cmd_m, rate_hz, n_modes)


def diagnose(
    rig: Rig,
    fit: Sequence[PathLike],
    validate: PathLike,
    columns: Optional[Union[str, Dict[str, Any]]] = None,
) -> Dict[str, Any]:
    """Diagnose the model of ``rig`` against recordings: ``beamtool diagnose``.

    Each recording is read and prepared by the library's entry point
    (``beamtools::diagnose::load``: camera gaps left out, glitches mended, sensor directions
    and zeros taken from the rest; its notes are issued as ``UserWarning``), the rig's
    parameters are calibrated on ``fit``, candidate effects (friction, cogging, servo lag,
    mount resonance, …) are located and selected by forward selection, and the result is
    validated on ``validate``.

    Args:
        rig: the :class:`Rig` (from a file).
        fit: recording CSVs to fit on (paths).
        validate: the recording held out for validation.
        columns: which column of every file holds which channel, with its scale to SI, as
            :func:`read_recording` takes it (``beamtool diagnose --columns``); ``None`` for
            files in the project's names.

    Returns:
        The CLI's JSON report (``--json``, ``beamtools::diagnose::report::to_json``) as Python
        objects (dicts, lists, floats, strings).

    Raises:
        OSError: a file cannot be read.
        ValueError: a recording the rig cannot simulate, without information, or inconsistent.
        KeyboardInterrupt: Ctrl-C (checked at each progress report).
    """
    return _beamshaper.diagnose(
        rig, [os.fspath(p) for p in fit], os.fspath(validate), columns
    )
