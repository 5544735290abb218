"""Type stubs of the Rust extension ``beamshaper._beamshaper`` (PyO3). The public names are
re-exported by ``beamshaper``; the functions there carry the full documentation."""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

F64Array = npt.NDArray[np.float64]
ArrayLike = Union[npt.NDArray[np.float64], npt.NDArray[np.float32], Sequence[float]]

class Recording:
    """A recording: time base (s) and optional channels of one axis, all of length N, SI units.

    Channels: ``tip_pos_m`` (absolute tip position, lab frame, m), ``base_pos_m`` (measured base
    position, m), ``base_cmd_m`` (commanded base position, m), ``force_n`` (motor force, N),
    ``tip_acc_m_s2`` (tip acceleration along the base axis, m/s²). Time may have logging gaps
    and jitter (``identify`` splits at gaps) but must be finite and strictly increasing.
    """

    @staticmethod
    def from_arrays(
        time_s: ArrayLike,
        tip_pos_m: Optional[ArrayLike] = None,
        base_pos_m: Optional[ArrayLike] = None,
        base_cmd_m: Optional[ArrayLike] = None,
        force_n: Optional[ArrayLike] = None,
        tip_acc_m_s2: Optional[ArrayLike] = None,
    ) -> "Recording":
        """A recording from numpy arrays of shape (N,) (float64 or float32, any strides; the
        values are copied once into the library). Raises ValueError: an array not 1-D, no
        channel besides ``time_s``, N < 2, lengths that differ, NaN or inf, time not strictly
        increasing (the message names the row)."""
    def to_dict(self) -> Dict[str, F64Array]:
        """``{"time_s": (N,), <each present channel>: (N,)}`` as new float64 arrays (SI)."""
    @property
    def time_s(self) -> F64Array:
        """Sample times (s), shape (N,)."""
    @property
    def channels(self) -> List[str]:
        """Names of the channels present besides ``time_s``."""
    @property
    def notes(self) -> List[str]:
        """What reading noted or mended (columns ignored, units converted, …)."""
    @property
    def sample_rate_hz(self) -> float:
        """1 / median sample interval (Hz)."""
    def __len__(self) -> int: ...

class Spectrum:
    """A spectrum file: a LabVIEW ``.lvm`` magnitude spectrum (kind ``"magnitude"``: frequency
    Hz, magnitude dB) or Klipper's PSD file (kind ``"klipper_psd"``: ``psd_x/y/z/xyz`` in
    (mm/s²)²/Hz, or divided by frequency when ``normalized``)."""

    @property
    def kind(self) -> str: ...
    @property
    def path(self) -> "os.PathLike[str]": ...
    @property
    def freq_hz(self) -> F64Array:
        """Frequency bins (Hz), shape (M,)."""
    def to_dict(self) -> Dict[str, Any]:
        """The columns as float64 arrays of shape (M,) (and ``unit`` / ``normalized``)."""

class Mode:
    """One mode: natural frequency ``freq_hz`` (Hz), damping ratio ``zeta`` (fraction), their
    1-σ ``freq_hz_std`` and ``zeta_std`` (the names of the JSON report) and ``method``."""

    def __init__(
        self,
        freq_hz: float,
        zeta: float,
        freq_hz_std: float = 0.0,
        zeta_std: float = 0.0,
        method: str = "given",
    ) -> None:
        """Raises ValueError: freq_hz ≤ 0, zeta outside [0, 1), negative or NaN 1-σ."""
    @property
    def freq_hz(self) -> float: ...
    @property
    def zeta(self) -> float: ...
    @property
    def freq_hz_std(self) -> float: ...
    @property
    def zeta_std(self) -> float: ...
    @property
    def method(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]: ...

class Identification:
    """The result of ``identify``: modes, the path taken and why, rejected estimates, warnings."""

    @property
    def modes(self) -> List[Mode]:
        """Physical modes, ascending in frequency."""
    @property
    def path(self) -> str:
        """The path taken (``free decay``, ``FRF (input/output)``, …)."""
    @property
    def reason(self) -> str:
        """Why this path, and what it used."""
    @property
    def warnings(self) -> List[str]: ...
    @property
    def rejected(self) -> List[Tuple[Mode, str]]:
        """Estimates that are not physical modes, with the reason."""
    @property
    def rayleigh(self) -> Optional[Tuple[float, float]]:
        """Rayleigh α1 (1/s), α2 (s) of the first two modes (paper eq. 22)."""
    @property
    def span_s(self) -> Tuple[float, float]:
        """Time span used (s)."""
    @property
    def sample_rate_hz(self) -> float: ...
    def to_dict(self) -> Dict[str, Any]:
        """The CLI's ``identify --json`` as Python objects."""
    def stabilisation(self) -> Optional[Dict[str, Any]]:
        """FRF path: ``{"diagram": {method, orders: [{order, poles: [[{freq_hz, zeta}, label]]}],
        modes}, "freq_hz": (M,), "h1_abs": (M,), "band_hz": (lo, hi)}``; ``None`` otherwise."""

class Shaper:
    """An input shaper (impulse sequence) designed by ``design_shaper``."""

    @property
    def name(self) -> str:
        """E.g. ``ZVD(6.055 Hz)`` or ``ZV(1.100 Hz) * EI(6.900 Hz)``."""
    @property
    def impulses(self) -> F64Array:
        """Shape (n, 2): column 0 ``time_s`` (s, first 0), column 1 ``amplitude`` (sums to 1)."""
    @property
    def duration_s(self) -> float:
        """Time of the last impulse (s): the delay the shaper adds to a move."""
    @property
    def worst_pct(self) -> float:
        """Worst-case percentage vibration over the modes' bands (%), or Klipper's remaining
        vibrations (%) for a design on a PSD."""
    @property
    def runners_up(self) -> List["Shaper"]:
        """Feasible longer designs (at most 5, by duration)."""
    @property
    def refused_on_recording(self) -> List[str]:
        """Shorter designs refused because they leave too much of the recorded vibration."""
    @overload
    def vibration_pct(self, freq_hz: float, zeta: float) -> float:
        """Percentage vibration V (%) left at natural frequency ``freq_hz`` (Hz, scalar or
        shape (M,)) and damping ratio ``zeta``: 100 · e^{−ζωt_n} √(C² + S²) with
        C = Σ Aᵢ e^{ζωtᵢ} cos(ω_d tᵢ), S the same with sin (paper eq. 27; Singer & Seering 1990).
        Raises ValueError: freq_hz ≤ 0 or NaN, zeta outside [0, 1)."""
    @overload
    def vibration_pct(self, freq_hz: ArrayLike, zeta: float) -> F64Array: ...
    def apply(self, signal: ArrayLike, rate_hz: float, path: str = "fixed") -> F64Array:
        """``signal`` (m, shape (N,), one sample per tick at ``rate_hz``) shaped by the firmware
        core's run-time engine exactly as the board runs it: the shaper sampled into a tap
        table at ``rate_hz``, the signal in nanometre counts, ``path`` ``"fixed"`` (Q2.30
        weights, exact unity DC gain) or ``"f32"``; the history starts at ``signal[0]``.
        Returns float64 (m), shape (N,). Raises ValueError: empty, NaN, |signal| ≥ 1 m (the
        engine's counts are below 2³⁰ nm), ``rate_hz`` ≤ 0, a shaper too long for the history."""

class Rig:
    """A rig file (TOML, e.g. ``rigs/paper.toml``): the beam, its base and sensors."""

    @staticmethod
    def from_toml(path: "str | os.PathLike[str]") -> "Rig":
        """Raises OSError (unreadable), ValueError (invalid TOML or parameters)."""
    @staticmethod
    def from_toml_str(text: str) -> "Rig": ...
    def modes(self, n: int = 6) -> Dict[str, Any]:
        """``beamtool modes --json``: ``beam_mass_kg``, Rayleigh ``rayleigh_alpha1_per_s`` /
        ``rayleigh_alpha2_s`` and per mode ``freq_hz_clamped_base``, ``freq_hz_free_base``
        (Hz), ``damping_ratio``, ``participation_kg_sqrt``, ``tip_per_modal_coordinate``, from
        the Galerkin model with ``n`` basis functions (paper eqs. 10–24)."""
    @property
    def sample_rate_hz(self) -> float:
        """The rig's sensor sample rate (Hz)."""

def read_recording(
    path: str, columns: Optional[Any] = None, axis: Optional[str] = None
) -> Union[Recording, Spectrum]: ...
def identify(
    recording: Union[Recording, Spectrum],
    f_min_hz: Optional[float] = None,
    f_max_hz: Optional[float] = None,
    path: str = "auto",
    method: str = "lscf",
    band_hz: Optional[Tuple[float, float]] = None,
    n_modes: Optional[int] = None,
) -> Identification: ...
def design_shaper(
    modes: Any,
    tolerance_pct: float = 2.0,
    min_band_pct: float = 2.0,
    recording: Optional[Recording] = None,
    signal: Optional[str] = None,
    move_mm: Optional[float] = None,
    speed_mm_s: float = 150.0,
    accel_mm_s2: float = 2000.0,
    board: Optional[Dict[str, int]] = None,
) -> Shaper: ...
def simulate(rig: Rig, base_cmd_m: ArrayLike, rate_hz: float, n_modes: int = 4) -> Recording: ...
def diagnose(
    rig: Rig,
    fit: List[str],
    validate: str,
    columns: Optional[Union[str, Dict[str, Any]]] = None,
) -> Dict[str, Any]: ...
