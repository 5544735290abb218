"""Plots of a design: the shaper's sensitivity curve, the FRF path's stabilisation diagram and
the verification of a shaper on a recorded free vibration.

matplotlib is optional: ``pip install matplotlib`` (or ``pip install ./python[plot]``). Each
function draws on ``ax`` (a new figure's axes when ``None``) and returns the axes.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from ._beamshaper import Identification, Recording, Shaper

_MISSING = (
    "beamshaper.plot needs matplotlib, which is not installed: "
    "pip install matplotlib (or pip install 'beamshaper[plot]')"
)


def _pyplot() -> Any:
    try:
        import matplotlib.pyplot as plt
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(_MISSING) from e
    return plt


def _axes(ax: Optional[Any]) -> Any:
    if ax is not None:
        return ax
    return _pyplot().subplots(figsize=(7, 4))[1]


def sensitivity(
    shaper: Shaper,
    ax: Optional[Any] = None,
    zeta: Optional[float] = None,
    f_max_hz: Optional[float] = None,
    modes: Optional[Any] = None,
    tolerance_pct: Optional[float] = None,
) -> Any:
    """Percentage vibration V(f) (%) of ``shaper`` (paper eq. 27, Fig. 5 style).

    Args:
        shaper: the :class:`~beamshaper.Shaper`.
        ax: matplotlib axes (default: a new figure).
        zeta: damping ratio of the curve (default: the first mode's, else 0).
        f_max_hz: upper end of the frequency axis (Hz; default 3 × the highest mode, or
            4 / the shaper's duration).
        modes: modes to mark (an Identification or a list of Mode); their bands are shaded.
        tolerance_pct: draws the tolerance line (%).

    Returns:
        The axes. Raises ImportError without matplotlib.
    """
    ax = _axes(ax)
    ms = list(modes.modes if isinstance(modes, Identification) else (modes or []))
    z = zeta if zeta is not None else (ms[0].zeta if ms else 0.0)
    top = f_max_hz or (3.0 * max(m.freq_hz for m in ms) if ms else 4.0 / max(shaper.duration_s, 1e-3))
    f = np.linspace(top / 2000.0, top, 2000)
    ax.plot(f, shaper.vibration_pct(f, z), label=f"{shaper.name} (ζ = {z:.4g})")
    for m in ms:
        ax.axvline(m.freq_hz, color="0.5", lw=0.8, ls="--")
    if tolerance_pct is not None:
        ax.axhline(tolerance_pct, color="tab:red", lw=0.8, label=f"tolerance {tolerance_pct} %")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("percentage vibration V (%)")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize="small")
    return ax


def stabilisation(identification: Identification, ax: Optional[Any] = None) -> Any:
    """The FRF path's stabilisation diagram: poles per model order over |H1(f)|.

    Markers: ``o`` frequency and damping stable, ``+`` frequency stable, ``.`` new; vertical
    lines the identified modes. Raises ValueError when the identification took another path
    (free decay, spectrum: no model orders), ImportError without matplotlib.
    """
    st = identification.stabilisation()
    if st is None:
        raise ValueError(
            f"no stabilisation diagram: the identification took the {identification.path} path "
            "(only the FRF path fits model orders)"
        )
    ax = _axes(ax)
    lo, hi = st["band_hz"]
    styles = {"Stable": ("o", "tab:green"), "Freq": ("+", "tab:blue"), "New": (".", "0.6")}
    for label, (marker, colour) in styles.items():
        pts = [
            (p[0]["freq_hz"], o["order"])
            for o in st["diagram"]["orders"]
            for p in o["poles"]
            if p[1] == label and lo <= p[0]["freq_hz"] <= hi
        ]
        if pts:
            x, y = zip(*pts)
            ax.plot(x, y, marker, color=colour, ms=4, ls="none", label=label.lower())
    for m in identification.modes:
        ax.axvline(m.freq_hz, color="tab:red", lw=0.8)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("model order")
    f, h = st["freq_hz"], st["h1_abs"]
    band = (f >= lo) & (f <= hi)
    ax2 = ax.twinx()
    ax2.semilogy(f[band], h[band], color="0.3", lw=0.8)
    ax2.set_ylabel("|H1|")
    ax.legend(fontsize="small", loc="upper left")
    return ax


def shaped_by_superposition(t_s: np.ndarray, x: np.ndarray, shaper: Shaper) -> np.ndarray:
    """Σᵢ Aᵢ · x(t − tᵢ): what a linear system's free vibration ``x`` becomes when the input
    that caused it is shaped (each impulse of the shaper replays the response, delayed and
    scaled; the model-free check of ``beamtool tune``). ``x`` before its start is taken as 0;
    shape (N,) like ``t_s`` (s)."""
    t_s = np.asarray(t_s, dtype=float)
    x = np.asarray(x, dtype=float)
    out = np.zeros_like(x)
    for t_i, a_i in shaper.impulses:
        out += a_i * np.interp(t_s - t_i, t_s, x, left=0.0, right=x[-1])
    return out


def verification(
    recording: Recording,
    shaper: Shaper,
    ax: Optional[Any] = None,
    channel: Optional[str] = None,
    start_s: Optional[float] = None,
) -> Any:
    """The recorded free vibration beside the same vibration shaped by ``shaper``
    (superposition, :func:`shaped_by_superposition`), from its largest excursion on.

    Args:
        recording: a recording of a free vibration (e.g. a plucked cantilever's decay).
        shaper: the shaper to check.
        channel: the channel (default ``tip_pos_m``, else ``tip_acc_m_s2``).
        start_s: where the free vibration starts (s; default its largest excursion).

    Returns:
        The axes; the title gives the residual's RMS as a percentage of the recorded one after
        the shaper's duration. Raises ValueError without that channel, ImportError without
        matplotlib.
    """
    d = recording.to_dict()
    name = channel or ("tip_pos_m" if "tip_pos_m" in d else "tip_acc_m_s2")
    if name not in d:
        raise ValueError(f"the recording has no {name} channel")
    t, x = d["time_s"], d[name] - np.median(d[name])
    k = int(np.argmax(np.abs(x))) if start_s is None else int(np.searchsorted(t, start_s))
    t, x = t[k:] - t[k], x[k:]
    y = shaped_by_superposition(t, x, shaper)
    after = t > shaper.duration_s
    pct = 100.0 * np.sqrt(np.mean(y[after] ** 2) / np.mean(x[after] ** 2))
    ax = _axes(ax)
    ax.plot(t, x, lw=0.7, color="0.6", label="recorded (unshaped)")
    ax.plot(t, y, lw=0.9, color="tab:blue", label=f"shaped by {shaper.name}")
    ax.set_xlabel("time from the largest excursion (s)")
    ax.set_ylabel(name)
    ax.set_title(f"residual after {shaper.duration_s:.3f} s: {pct:.2f} % RMS of the recorded")
    ax.legend(fontsize="small")
    return ax
