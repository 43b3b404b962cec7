"""The gap over frequency: band power of the force residuals, real vs the simulator's own scatter.

For each force axis, the residual against the nominal replay (real − sim) and the null residual (a
replay with the sim's noise and a drawn specimen − sim) are cut into Welch segments; their mean power
in each band tells whether the gap is slow (drift, softening, a void: < 1 Hz), at the feed's time
scale, or a vibration (runout aliased to ~33 Hz).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from drillgym.envs.constants import FT_RATE_HZ
from drillgym.eval.diagnosis.channels import FORCE_CHANNELS

BANDS_HZ = ((0.0, 1.0), (1.0, 5.0), (5.0, 20.0), (20.0, 50.0))
"""Frequency bands (Hz)."""
SEGMENT = 128
"""Welch segment length (samples, 1.28 s)."""


def band_powers(residual: np.ndarray) -> np.ndarray:
    """Power (N²) of each force axis of a residual (n, 3) in each band, (n_bands, 3); NaN if too short."""
    out = np.full((len(BANDS_HZ), 3), np.nan)
    for k in range(3):
        x = residual[:, k]
        x = x[np.isfinite(x)]
        if x.size < SEGMENT:
            continue
        f, p = _welch()(x, fs=FT_RATE_HZ, nperseg=SEGMENT)
        df = f[1] - f[0]
        for b, (lo, hi) in enumerate(BANDS_HZ):
            sel = (f >= lo) & (f < hi) if hi < FT_RATE_HZ / 2 else (f >= lo)
            out[b, k] = float(p[sel].sum() * df)
    return out


def spectrum_summary(real: list[np.ndarray], null: list[np.ndarray]) -> dict[str, Any]:
    """Mean band powers of real and null residuals over episodes (each (n, 3) force residuals)."""
    r = np.nanmean([band_powers(x) for x in real], axis=0)
    n = np.nanmean([band_powers(x) for x in null], axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = r / n
    return {
        "bands_hz": [list(b) for b in BANDS_HZ],
        "channels": list(FORCE_CHANNELS),
        "real_n2": r.T.tolist(),
        "null_n2": n.T.tolist(),
        "ratio": ratio.T.tolist(),
    }


PEAK_BAND_HZ = (5.0, 45.0)
"""Where :func:`excess_peak_hz` looks for a ringing (Hz): above the feed's time scale, below the F/T's Nyquist limit."""


AXIS_GROUPS = {"lateral": (0, 1), "axial": (2,)}
"""Force axes whose residual spectra :func:`excess_peak_hz` reads together: a mount bends and stretches apart."""


def excess_peak_hz(real: list[np.ndarray], null: list[np.ndarray], axes: tuple[int, ...] = (0, 1, 2)) -> float | None:
    """The frequency (Hz) where the real force residuals' power most exceeds the simulator's own, in :data:`PEAK_BAND_HZ`.

    Welch spectra of the force ``axes``, summed over them and averaged over episodes (``real`` and ``null`` as in
    :func:`spectrum_summary`). None where the real power nowhere exceeds twice the null's (no ringing to read).
    """
    r, n = _mean_psd(real), _mean_psd(null)
    return None if r is None or n is None else _peak(r[0], r[1][:, list(axes)], n[1][:, list(axes)])


def excess_peaks_hz(real: list[np.ndarray], null: list[np.ndarray]) -> dict[str, float | None]:
    """:func:`excess_peak_hz` of all three force axes (``all``) and of each of :data:`AXIS_GROUPS` (spectra made once)."""
    r, n = _mean_psd(real), _mean_psd(null)
    groups = {"all": (0, 1, 2)} | AXIS_GROUPS
    if r is None or n is None:
        return dict.fromkeys(groups)
    return {g: _peak(r[0], r[1][:, list(a)], n[1][:, list(a)]) for g, a in groups.items()}


def _mean_psd(residuals: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
    """Frequencies and each force axis's Welch spectrum averaged over the episodes long enough, (n_f, 3)."""
    spectra = []
    for x in residuals:
        x = x[np.all(np.isfinite(x), axis=1)]
        if x.shape[0] >= SEGMENT:
            f, p = _welch()(x, fs=FT_RATE_HZ, nperseg=SEGMENT, axis=0)
            spectra.append(p)
    return (f, np.mean(spectra, axis=0)) if spectra else None


def _peak(f: np.ndarray, real_psd: np.ndarray, null_psd: np.ndarray) -> float | None:
    """Where the axes' summed real power most exceeds twice the null's, in :data:`PEAK_BAND_HZ` (None: nowhere)."""
    pr, pn = real_psd.sum(axis=1), null_psd.sum(axis=1)
    band = (f >= PEAK_BAND_HZ[0]) & (f <= PEAK_BAND_HZ[1])
    excess = np.where(band & (pr > 2.0 * pn), pr - pn, 0.0)
    return float(f[int(np.argmax(excess))]) if excess.max() > 0.0 else None


def _welch() -> Any:
    """SciPy's Welch estimate, imported on first use.

    ``scipy.signal`` takes ~1.3 s to import, and the diagnosis's workers, which import this package, never
    compute a spectrum.
    """
    from scipy.signal import welch

    return welch
