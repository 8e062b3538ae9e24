"""Analysis of a run file into its ``/analysis`` group (paper §2.2, §3; docs/model.md §3; docs/analysis.md).

:func:`analyze_run` computes, from one run file written by :mod:`aca_warp.hf.runfile`,

* ``/analysis/spectra``: Hann amplitude spectra of every global output (mean-normalised, paper Fig. 8);
* ``/analysis/patch_spectrum``: the mean over patches of the per-patch velocity amplitude spectra
  (when per-patch velocities were recorded);
* ``/analysis/stft`` and ``/analysis/cwt``: time-frequency maps of μ(t) (paper Figs. 10, 11);
* ``/analysis/sync``: the Synchronization Index S(f) with Φ(f), its null level and R_w(f) (paper §2.2,
  Fig. 9; only with per-patch velocities);
* ``/analysis/peaks``: attributes with the first velocity-spectrum peak and the largest μ peak;
* ``/analysis/saturation``: where the record's growth saturates (Σ|u̇| and μ), with the measured growth rate beside
  the predicted one the run file holds (:func:`compute_saturation`).

Everything is computed first and written last, into a temporary group that replaces ``/analysis`` only
once it is complete: a failure leaves the previous ``/analysis`` (or none) in place. The ``compute_*``
functions are public so that :mod:`aca_warp.plots` can compute on the fly what a file does not hold
(:func:`analysis_group`). The groups of the per-patch velocities are computed in :mod:`aca_warp.analysis.patch_report`
and :class:`Group` is defined in :mod:`aca_warp.analysis.groups`; both are importable from here too.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from aca_warp.common.bounds import json_attribute
from aca_warp.common.errors import SceneError, option
from aca_warp.common.files import attr_value

from .groups import DEFAULT_BAND_TOP as DEFAULT_BAND_TOP
from .groups import GROUP, TMP_GROUP
from .groups import MIN_SAMPLES as MIN_SAMPLES
from .groups import Group as Group
from .groups import has_patch_velocity as has_patch_velocity
from .groups import missing_run_message as missing_run_message
from .groups import open_h5_run as open_h5_run
from .groups import sample_interval as sample_interval
from .patch_report import LEAKAGE_BINS as LEAKAGE_BINS
from .patch_report import bin_width as bin_width
from .patch_report import compute_patch_spectrum as compute_patch_spectrum
from .patch_report import compute_patch_velocity as compute_patch_velocity
from .patch_report import compute_sync as compute_sync
from .patch_report import leakage_floor as leakage_floor
from .patch_report import lowest_bin_remark as lowest_bin_remark
from .patch_report import shown_bins as shown_bins
from .patch_report import sync_excess as sync_excess
from .saturation import record_saturation
from .spectra import DEFAULT_FLOOR_HZ, amplitude_spectrum, peak
from .timefreq import check_stft_window, cwt_morlet, default_window_samples, stft

GLOBAL_OUTPUTS = ("mu", "torque", "friction_radius", "sum_velocity", "sum_abs_velocity", "friction_centroid")
"""Global outputs of a run file (datasets under ``/global``), in the order of ``aca_warp.hf.recorder.GLOBAL_NAMES``.
Run files of versions before the friction centroid lack it; everything else is required."""

LABELS = {
    "mu": "μ",
    "torque": "friction torque T",
    "friction_radius": "friction radius r_eff",
    "sum_velocity": "Σ u̇",
    "sum_abs_velocity": "Σ |u̇|",
    "friction_centroid": "friction centroid |Σ F r⃗| / |Σ F|",
}
"""Short names of the global outputs for captions and legends."""

PEAK_FLOOR_HZ = 1.0e3
"""Velocity and μ peaks are searched above this frequency [Hz] (and above 3 frequency bins)."""

RULES = ("relative", "snr")


# ----------------------------------------------------------------------------------------- run files


def _decode(value: Any) -> Any:
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, np.generic):
        value = value.item()
    return value


def run_attr(f: h5py.File, name: str, default: Any = None) -> Any:
    """Root attribute ``name`` of a run file, JSON-decoded where it holds JSON."""
    return attr_value(f.attrs[name]) if name in f.attrs else default


def check_run_file(
    f: h5py.File, name: str | Path = "", *, min_samples: int = MIN_SAMPLES, needed_by: str = "the analysis"
) -> None:
    """Refuse an HDF5 file that is not an aca_warp run file, or holds fewer than the ``min_samples`` samples that
    ``needed_by`` needs (:class:`SceneError`, one line)."""
    where = f"{name}: " if name else ""
    missing = [f"/global/{k}" for k in ("time", *GLOBAL_OUTPUTS[:5]) if f"global/{k}" not in f]
    missing += [f"/patches/{k}" for k in ("x", "y", "area") if f"patches/{k}" not in f]
    if "scene" not in f.attrs:
        missing.append("root attribute 'scene'")
    if missing:
        raise SceneError(f"{where}not an aca_warp run file (lacks {', '.join(missing)})")
    if not isinstance(json_attribute(f.attrs["scene"], f"{where}attribute 'scene'"), dict):
        raise SceneError(f"{where}attribute 'scene' is not a JSON object (a crafted or damaged file)")
    for k in ("global/time", *(f"global/{k}" for k in GLOBAL_OUTPUTS), "patches/x", "patches/y", "patches/area",
              "patches/time"):  # fmt: skip
        if k in f and not isinstance(f[k], h5py.Dataset):
            raise SceneError(f"{where}/{k} is a {type(f[k]).__name__.lower()}, not a dataset")
    n = f["global/time"].shape
    for k in (k for k in GLOBAL_OUTPUTS if f"global/{k}" in f):
        if f[f"global/{k}"].shape != n or len(n) != 1:
            raise SceneError(f"{where}/global/{k} has shape {f[f'global/{k}'].shape}, /global/time {n}")
    m = f["patches/x"].shape
    for k in ("x", "y", "area"):
        if f[f"patches/{k}"].shape != m or len(m) != 1:
            raise SceneError(f"{where}/patches/{k} has shape {f[f'patches/{k}'].shape}, expected one value per patch")
    if n[0] < min_samples:
        held = f"{n[0]} sample" + ("" if n[0] == 1 else "s")
        raise SceneError(f"{where}the run holds {held}; {needed_by} needs at least {min_samples}")
    if "patches/velocity" in f:
        pt = f["patches/time"] if "patches/time" in f else None
        v, rows = f["patches/velocity"], pt.shape[0] if pt is not None and pt.ndim == 1 else -1
        if v.ndim != 2 or v.shape != (rows, f["patches/x"].shape[0]):
            raise SceneError(f"{where}/patches/velocity has shape {v.shape}, expected (len(/patches/time), patches)")


def open_run_file(
    path: str | Path, mode: str = "r", *, min_samples: int = MIN_SAMPLES, needed_by: str = "the analysis"
) -> h5py.File:
    """Open and check an HF run file as an h5py File (:func:`~aca_warp.common.files.open_h5`); :class:`SceneError`
    if it is missing (naming its ``.partial`` where that exists), held open by another process (HDF5's file lock),
    not HDF5, an LF run file or not a run file, or holds fewer than ``min_samples`` samples (said as what
    ``needed_by`` needs). (:func:`aca_warp.open_run` reads any run file into an xarray Dataset.)"""
    p = Path(path)
    f = open_h5_run(p, mode)
    try:
        if _decode(f.attrs.get("kind")) == "lf":
            raise SceneError(
                f"{p} is an LF run file: the analysis applies to HF run files (aca-warp hf); "
                f"draw its figures with 'aca-warp plot {p} -o DIR'"
            )
        check_run_file(f, p, min_samples=min_samples, needed_by=needed_by)
    except BaseException:
        f.close()
        raise
    return f


# ------------------------------------------------------------------------------------------- compute


def _normalisable(x: np.ndarray) -> bool:
    """Mean normalisation is meaningful for a signal of one sign with a non-zero mean."""
    return bool((np.all(x >= 0) or np.all(x <= 0)) and np.mean(x) != 0.0)


def compute_spectra(f: h5py.File) -> Group:
    """Hann amplitude spectra of every global output, normalised to the signal's mean (paper Fig. 8).

    A signal that changes sign (Σu̇ typically) or has zero mean keeps its physical amplitude: a mean near
    zero would make the normalised spectrum arbitrary. Each dataset's ``normalisation`` says which.
    """
    time = f["global/time"][()]
    dt = sample_interval(time)
    g = Group(
        attrs={
            "window": f"periodic Hann window over the whole record ({time.size} samples, {time.size * dt:.6g} s)",
            "scaling": "one-sided, coherent-gain corrected: a sinusoid a·sin(2πft) on a bin shows a; bin 0 the mean",
            "normalisation": "each spectrum divided by |mean| of its raw signal (dimensionless), except signals "
            "that change sign or have zero mean (physical units)",
            "resolution": f"Δf = {1.0 / (time.size * dt):.6g} Hz",
            "sample_interval": dt,
            "samples": time.size,
        }
    )
    freq = None
    for name in (k for k in GLOBAL_OUTPUTS if f"global/{k}" in f):
        x = f[f"global/{name}"][()].astype(np.float64)
        unit = _decode(f[f"global/{name}"].attrs.get("unit", "1"))
        mean = float(np.mean(x))
        normalised = _normalisable(x)
        if normalised:
            freq, amp = amplitude_spectrum(x, dt, normalise="mean")
            norm, amp_unit = f"divided by |mean| = {abs(mean):.6g} {unit}", "1"
        else:
            freq, amp = amplitude_spectrum(x, dt, normalise=None)
            norm, amp_unit = f"none: the signal changes sign or has zero mean (mean {mean:.4g} {unit})", unit
        g.add(
            name,
            amp,
            amp_unit,
            signal=f"/global/{name}",
            label=LABELS[name],
            window="periodic Hann",
            scaling="one-sided amplitude, coherent-gain corrected",
            normalisation=norm,
            normalised=normalised,
            mean=mean,
            signal_unit=unit,
        )
    g.datasets = {"freq": (freq, {"unit": "Hz"}), **g.datasets}
    return g


def default_stft_window(n: int, dt: float, top: float = DEFAULT_BAND_TOP) -> float:
    """STFT window [s] of ``analyze`` for ``n`` samples at ``dt`` [s], a power of two of samples:

    * 2^round(log2(N/64)) samples, at least 16 (``timefreq.stft``'s default);
    * if that resolves Δf > top/8 (25 kHz for the default band top of 200 kHz; top is capped at the Nyquist
      frequency), the smallest power of two with Δf = 1/(samples·dt) ≤ top/8 (rounded up: 40 samples needed give 64);
    * at most the largest power of two ≤ N/2 (at least 4), so that the map has five or more windows: on records too
      short for Δf ≤ top/8 the resolution is the best those allow.
    """
    return default_window_samples(n, at_least=8.0 / (min(top, 0.5 / dt) * dt)) * dt  # Δf ≤ top/8


def compute_stft(f: h5py.File, *, window_s: float | None = None, detrend: str | None = "linear") -> Group:
    """STFT amplitude of μ(t) (``timefreq.stft``; linear trend removed per window), float32.

    ``window_s`` defaults to :func:`default_stft_window`. A window of fewer than 4 samples, or one that leaves fewer
    than 2 windows in the record (a map of one column shows nothing), is refused in one line (:class:`SceneError`,
    in seconds and samples).
    """
    mu = f["global/mu"][()]
    dt = sample_interval(f["global/time"][()])
    name = "the default STFT window" if window_s is None else option("stft_window_s", "--stft-window")
    if window_s is None:
        window_s = default_stft_window(mu.size, dt)
    nperseg = round(window_s / dt)
    try:  # the map needs MIN_STFT_WINDOWS columns (stft alone accepts one)
        check_stft_window(nperseg, max(1, nperseg // 4), mu.size, dt, name="window", seconds=window_s)
        times, freqs, amp, info = stft(mu, dt, window_s=window_s, detrend=detrend)
    except ValueError as e:
        raise SceneError(f"STFT of mu: {str(e).replace('window', name, 1)}") from None
    t0 = float(f["global/time"][0])
    g = Group(attrs={"signal": "/global/mu", **info})
    g.add("time", times + t0, "s", meaning="window centres")
    g.add("freq", freqs, "Hz")
    g.add("amplitude", amp.astype(np.float32), "1", caption=info["caption"], quantity=info["quantity"])
    return g


def default_cwt_freqs(
    n: int, dt: float, *, freq_range: tuple[float, float] | None = None, count: int = 96
) -> np.ndarray:
    """Log-spaced CWT frequencies [Hz]: from max(10 Hz, 4/T) to min(200 kHz, 0.4/dt), or ``freq_range`` (from no
    lower than 4/T: at least 4 periods in the record; up to 0.45/dt). A band wholly below 4/T (a short record) keeps
    its top and reaches down a decade, never below ``freq_range``'s lower edge; a band wholly above 0.45/dt gives the
    decade below 0.45/dt. :func:`compute_cwt` says so in either case."""
    record = n * dt
    hi_default = min(DEFAULT_BAND_TOP, 0.4 / dt)
    if freq_range is None:
        lo, hi = max(DEFAULT_FLOOR_HZ, 4.0 / record), hi_default
    else:
        lo = max(float(freq_range[0]), 4.0 / record, 1e-3)
        hi = min(float(freq_range[1]), 0.45 / dt)
    if not hi > lo and freq_range is not None:
        lo = max(float(freq_range[0]), 1e-3, hi / 10.0)
    if not hi > lo:  # no band at all: the decade below the top (a band above 0.45/dt: compute_cwt says so)
        lo = hi / 10.0
    return np.geomspace(lo, hi, count)


CWT_SAMPLES_PER_PERIOD = 16.0
"""A CWT frequency f is computed on the record resampled to no fewer than this many samples per 1/f."""


def downsample(x: np.ndarray, q: int) -> np.ndarray:
    """Low-pass and keep every q-th sample: Kaiser FIR (80 dB), flat to 1/(8·q·dt), stop from 1/(4·q·dt)."""
    from scipy.signal import firwin, kaiserord, resample_poly

    taps, beta = kaiserord(80.0, 0.25 / q)
    h = firwin(taps | 1, 0.375 / q, window=("kaiser", beta))
    return resample_poly(x, 1, q, window=h)


def multirate_cwt(
    x: np.ndarray, dt: float, freqs: np.ndarray, *, stride: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, str]]:
    """``cwt_morlet`` with each frequency computed on a record downsampled by a power of two q ≤ ``stride``.

    q is the largest power of two with 1/(q·dt) ≥ 16 f. The record is low-passed and downsampled by
    :func:`downsample` (sample j of the result at input sample j·q), so a wavelet of frequency f spans
    16 or more samples per period instead of up to millions: low frequencies become cheap. The filter
    passes f and the wavelet's band (up to ~2 f) unchanged and removes what lies above half the new
    Nyquist frequency, where PyWavelets' sampled wavelets would leak. ``stride`` must be a power of two;
    the output keeps every ``stride``-th input sample, so all groups share one time grid.
    """
    if stride & (stride - 1):
        raise ValueError(f"stride must be a power of two, got {stride}")
    n = x.size
    q_max = np.floor(np.log2(np.maximum(1.0, 1.0 / (CWT_SAMPLES_PER_PERIOD * freqs * dt))))
    q = (2 ** np.minimum(q_max, np.log2(stride))).astype(np.int64)
    out = np.empty((freqs.size, -(-n // stride)), dtype=x.dtype)
    info: dict[str, str] = {}
    for qi in np.unique(q):
        idx = np.flatnonzero(q == qi)
        xq = x if qi == 1 else downsample(x, int(qi))
        _, _, w, info = cwt_morlet(xq, dt * qi, freqs[idx], stride=stride // int(qi))
        out[idx] = w[:, : out.shape[1]]
    info = dict(info)
    factors = ", ".join(str(int(v)) for v in np.unique(q))
    info["multirate"] = (
        f"frequencies computed on the record low-passed and downsampled by q in {{{factors}}}, "
        f"at least {CWT_SAMPLES_PER_PERIOD:g} samples per period"
    )
    return np.arange(0, n, stride) * dt, freqs, out, info


def compute_cwt(
    f: h5py.File,
    *,
    freqs: Sequence[float] | np.ndarray | None = None,
    freq_range: tuple[float, float] | None = None,
    count: int = 96,
    columns: int = 2048,
) -> Group:
    """Complex-Morlet CWT amplitude of μ(t) − mean(μ) (``timefreq.cwt_morlet``), time axis decimated.

    Every ``stride``-th time sample of |W| is kept (float32), stride the smallest power of two with
    ceil(N/stride) ≤ ``columns``; low frequencies are computed on a downsampled record (:func:`multirate_cwt`).
    :class:`SceneError` for no frequency or ``columns`` < 2 (a map of one column shows nothing).
    """
    mu = f["global/mu"][()].astype(np.float64)
    time = f["global/time"][()]
    dt = sample_interval(time)
    derived = freqs is None  # the remarks below are on the frequencies chosen here, not on ones given
    if freqs is None:
        freqs = default_cwt_freqs(mu.size, dt, freq_range=freq_range, count=count)
    freqs = np.asarray(freqs, dtype=np.float64)
    if freqs.ndim != 1 or freqs.size < 1:
        raise SceneError(f"the CWT needs at least one frequency, got {freqs.size}")
    if columns < 2:
        raise SceneError(f"the CWT map needs at least 2 time columns, got columns = {columns}")
    stride = 1 << max(0, math.ceil(math.log2(max(1.0, mu.size / max(1, columns)))))
    mean = float(np.mean(mu))
    if np.any(freqs <= 0) or np.any(freqs >= 0.5 / dt):
        raise SceneError(f"CWT frequencies must lie in (0, {0.5 / dt:g}) Hz (the Nyquist frequency)")
    times, out_freqs, amp, info = multirate_cwt(mu - mean, dt, freqs, stride=stride)
    record = mu.size * dt
    if derived and freq_range is not None and freqs[0] < float(freq_range[0]):
        info["below_band"] = (
            f"the band lies above the CWT's top, 0.45/Δt = {0.45 / dt / 1e3:.4g} kHz: the map spans the decade "
            "below that"
        )
    if derived and freqs[0] < 4.0 / record:
        info["few_periods"] = (
            f"the record ({record:.4g} s) holds fewer than 4 periods below {4.0 / record / 1e3:.4g} kHz: the "
            "wavelets of the map's lower frequencies reach past its ends"
        )
    info["mean_removed"] = f"mean(μ) = {mean:.6g} subtracted before the transform"
    info["decimation"] = (
        "Every time sample of |W| kept"
        if stride == 1
        else f"Every {stride}-th time sample of |W| kept ({stride * dt:.4g} s)"
    )
    g = Group(attrs={"signal": "/global/mu", **info})
    g.add("time", times + float(time[0]), "s")
    g.add("freq", out_freqs, "Hz")
    g.add("amplitude", amp.astype(np.float32), "1", caption=info["caption"], quantity=info["quantity"])
    return g


def _peak_band(freq: np.ndarray, freq_range: tuple[float, float] | None) -> tuple[float, float]:
    lo = max(PEAK_FLOOR_HZ, 3.0 * float(freq[1] - freq[0]))
    hi = float(freq[-1])
    if freq_range is not None:
        lo, hi = max(lo, float(freq_range[0])), min(hi, float(freq_range[1]))
    return lo, hi


def band_edge(freq: np.ndarray, amp: np.ndarray, fmin: float, fmax: float) -> str:
    """Whether the largest bin of ``amp`` in ``fmin`` ≤ f ≤ ``fmax`` [Hz] (what :func:`~aca_warp.analysis.spectra.peak`
    returns) lies on a band edge without being a local maximum of the whole spectrum: ``"lower"`` or ``"upper"``
    (the spectrum still rises beyond that edge, or the edge is the spectrum's end: no peak inside the band), else
    ``"no"`` (an interior local maximum, or an edge bin that its outer neighbour does not exceed)."""
    band = np.flatnonzero((freq >= fmin) & (freq <= fmax))
    if band.size == 0:
        return "no"
    i = int(band[np.argmax(amp[band])])
    if i == band[0] and (i == 0 or amp[i - 1] >= amp[i]):
        return "lower"
    if i == band[-1] and (i == amp.size - 1 or amp[i + 1] >= amp[i]):
        return "upper"
    return "no"


def compute_peaks(
    spectra: Group, patch_spectrum: Group | None = None, *, freq_range: tuple[float, float] | None = None
) -> Group:
    """Largest spectral peaks above 1 kHz (and above 3 bins, clear of the Hann leakage of the mean).

    The *first velocity-spectrum peak* is that of the mean per-patch velocity amplitude spectrum when the
    run holds per-patch velocities, else that of the Σu̇ spectrum. The Σ|u̇| peak is stored too, but it is
    not used as the velocity peak: rectification moves a patch oscillating at f to 2f and its harmonics.
    A largest bin on a band edge that is no local maximum (:func:`band_edge`) is still stored, with
    ``<name>_peak_at_band_edge`` (and ``first_velocity_peak_at_band_edge``) ``"lower"`` or ``"upper"`` instead
    of ``"no"``: the band then holds no peak, only the foot of one outside it.
    """
    freq = spectra["freq"]
    lo, hi = _peak_band(freq, freq_range)
    attrs: dict[str, Any] = {"band": [lo, hi], "band_unit": "Hz", "method": "largest bin, Gaussian interpolation"}
    candidates = {}
    edges: dict[str, str] = {}
    for name in ("mu", "sum_velocity", "sum_abs_velocity"):
        try:
            candidates[name] = (*peak(freq, spectra[name], fmin=lo, fmax=hi), spectra.meta(name)["unit"])
        except ValueError:
            continue
        edges[name] = band_edge(freq, spectra[name], lo, hi)
    if patch_spectrum is not None:
        pf = patch_spectrum["freq"]
        plo, phi = _peak_band(pf, freq_range)
        try:
            candidates["patch_velocity"] = (*peak(pf, patch_spectrum["mean_amplitude"], fmin=plo, fmax=phi), "m s-1")
            edges["patch_velocity"] = band_edge(pf, patch_spectrum["mean_amplitude"], plo, phi)
        except ValueError:
            pass
    for name, (fp, ap, unit) in candidates.items():
        attrs[f"{name}_peak_frequency"] = fp
        attrs[f"{name}_peak_frequency_unit"] = "Hz"
        attrs[f"{name}_peak_amplitude"] = ap
        attrs[f"{name}_peak_amplitude_unit"] = unit
        attrs[f"{name}_peak_at_band_edge"] = edges[name]
    source = "patch_velocity" if "patch_velocity" in candidates else "sum_velocity"
    if source in candidates:
        fp, ap, unit = candidates[source]
        attrs["first_velocity_peak_frequency"] = fp
        attrs["first_velocity_peak_frequency_unit"] = "Hz"
        attrs["first_velocity_peak_amplitude"] = ap
        attrs["first_velocity_peak_amplitude_unit"] = unit
        attrs["first_velocity_peak_at_band_edge"] = edges[source]
        attrs["first_velocity_peak_source"] = (
            "mean per-patch velocity amplitude spectrum (/analysis/patch_spectrum)"
            if source == "patch_velocity"
            else "Σu̇ amplitude spectrum (/analysis/spectra/sum_velocity)"
        )
    return Group(attrs=attrs)


# ------------------------------------------------------------------------------------------ saturation


def _predicted_rates(f: h5py.File) -> dict[str, float]:
    """Percentiles of the run file's ``/patches/predicted_growth_rate`` σ_i [1/s] (empty for files without it)."""
    if "patches/predicted_growth_rate" not in f:
        return {}
    sigma = f["patches/predicted_growth_rate"][()].astype(np.float64)
    q = np.percentile(sigma, [0.0, 25.0, 50.0, 100.0])
    return dict(zip(("min", "q25", "median", "max"), (float(v) for v in q), strict=True))


def compute_saturation(f: h5py.File) -> Group:
    """Saturation of the run's record (``saturation.record_saturation`` on /global/sum_abs_velocity and /global/mu).

    Attributes: ``status`` ("saturated", "not saturated", "no growth phase", or "not analysed" for a record shorter
    than 64 samples, with ``reason``), ``t_start`` [s] (the later of ``t_s_sum_abs_velocity`` and ``t_s_mu``),
    the measured ``growth_rate`` of Σ|u̇| over ``growth_window`` [s] with ``growth_r2`` and ``growth_rise``
    [e-folds], ``mu_growth_rate``, both verdicts, ``record_length`` [s], and (where the run file holds σ_i)
    ``predicted_growth_rate_*``
    (min, q25, median, max) and ``growth_rate_ratio`` = measured / predicted median. Datasets: the envelopes of
    both signals per window with their log-slopes. Absent values are stored as "none".
    """
    time = f["global/time"][()]
    attrs: dict[str, Any] = {"signals": ["/global/sum_abs_velocity", "/global/mu"], "method": "docs/analysis.md"}
    predicted = _predicted_rates(f)
    attrs.update({f"predicted_growth_rate_{k}": v for k, v in predicted.items()})
    attrs["predicted_source"] = "/patches/predicted_growth_rate" if predicted else "none (not in this run file)"
    attrs["record_length"] = float(time[-1] - time[0]) if time.size > 1 else 0.0
    attrs["record_length_unit"] = "s"
    try:
        sample_interval(time)
        rec = record_saturation(time, f["global/mu"][()], f["global/sum_abs_velocity"][()])
    except (ValueError, SceneError) as e:
        return Group(attrs={**attrs, "status": "not analysed", "reason": str(e), "t_start": None})
    figures = rec.figures()
    figures["growth_window"] = list(figures["growth_window"]) if figures["growth_window"] else None
    attrs.update(figures)
    rate = figures["growth_rate"]
    attrs["growth_rate_ratio"] = rate / predicted["median"] if rate is not None and predicted.get("median") else None
    for key in ("t_start", "t_s_sum_abs_velocity", "t_s_mu", "growth_window"):
        attrs[f"{key}_unit"] = "s"
    for key in ("growth_rate", "mu_growth_rate", "predicted_growth_rate"):
        attrs[f"{key}_unit"] = "s-1"
    g = Group(attrs=attrs)
    for name, res, unit in (("sum_abs_velocity", rec.sum_abs_velocity, "m s-1"), ("mu", rec.mu, "1")):
        g.add(f"{name}_time", res.envelope_time, "s", meaning="window centres")
        g.add(f"{name}_envelope", res.envelope, unit, statistic=res.statistic, window=res.window)
        g.add(f"{name}_log_slope", res.log_slope, "s-1", meaning="local slope of ln envelope")
    return g


def _predicted_e_folds(a: dict[str, Any]) -> float | None:
    """σ_pred·T: e-folds of the predicted σ median over the record length T (None where either is missing)."""
    sigma, length = a.get("predicted_growth_rate_median"), a.get("record_length")
    if sigma is None or length is None or isinstance(sigma, str) or isinstance(length, str):
        return None
    return float(sigma) * float(length)


def saturation_summary(g: Group) -> str:
    """One line of the ``analyze`` summary: whether the record is saturated, from when, and the measured
    growth rate beside the predicted median and 25th percentile. A record without a growth phase that spans less
    than one e-fold of the predicted σ median (σ_pred·T < 1, T the record length) is called too short to tell, not
    settled: the detector needs a rise of at least one e-fold to see growth."""
    a = g.attrs
    status = a["status"]
    if status == "not analysed":
        return f"saturation not analysed ({a['reason']})"

    def ms(t: Any) -> str:
        return "none" if t is None or t == "none" else f"{float(t) * 1e3:.4g} ms"

    if status == "saturated":
        text = f"saturated from {ms(a['t_start'])} (Σ|u̇| {ms(a['t_s_sum_abs_velocity'])}, μ {ms(a['t_s_mu'])})"
    elif status == "no growth phase":
        folds = _predicted_e_folds(a)
        if folds is not None and 0.0 < folds < 1.0:  # σ_pred ≤ 0: a stable pad, whose settling is the verdict
            text = f"no growth phase: record too short to tell (σ_pred·T = {folds:.2g} e-folds)"
        else:
            text = f"no growth phase (Σ|u̇| settled from {ms(a['t_s_sum_abs_velocity'])} without growing)"
    else:
        text = "not saturated (Σ|u̇| still changes at the end of the record)"
    rate = a.get("growth_rate")
    measured = "no growth phase fitted" if rate is None or rate == "none" else f"growth {float(rate):.4g} s^-1"
    if "predicted_growth_rate_median" in a:
        pm, pq = a["predicted_growth_rate_median"], a["predicted_growth_rate_q25"]
        return f"{text}; {measured} (predicted σ median {pm:.4g}, 25th percentile {pq:.4g} s^-1)"
    return f"{text}; {measured} (no predicted σ in this run file)"


# ---------------------------------------------------------------------------------------- read/write


def _attr_value(v: Any) -> Any:
    if isinstance(v, (str, bool, int, float, np.number, np.bool_)):
        return v
    if v is None:
        return "none"
    if isinstance(v, (list, tuple)) and all(isinstance(x, (int, float, np.number)) for x in v):
        return np.asarray(v, dtype=np.float64)
    return json.dumps(v, default=_json_plain)


def _json_plain(v: Any) -> Any:
    """A NumPy scalar or array as the Python number or list that JSON stores (``json.dumps``' ``default``)."""
    if isinstance(v, (np.generic, np.ndarray)):
        return v.tolist()
    raise TypeError(f"{type(v).__name__} cannot be stored as JSON")


def _write_group(parent: h5py.Group, name: str, group: Group) -> None:
    g = parent.create_group(name)
    for k, v in group.attrs.items():
        g.attrs[k] = _attr_value(v)
    for dname, (data, attrs) in group.datasets.items():
        _write_dataset(g, dname, data, attrs)


def _write_dataset(g: h5py.Group, name: str, data: np.ndarray, attrs: dict[str, Any]) -> None:
    d = g.create_dataset(name, data=data)
    for k, v in attrs.items():
        d.attrs[k] = _attr_value(v)


def read_group(g: h5py.Group) -> Group:
    """An ``/analysis/<name>`` group read back into a :class:`Group`."""
    out = Group(attrs={k: _decode(v) for k, v in g.attrs.items()})
    for name, d in g.items():
        if isinstance(d, h5py.Dataset):
            out.datasets[name] = (d[()], {k: _decode(v) for k, v in d.attrs.items()})
    return out


def analysis_fits(f: h5py.File) -> bool:
    """Whether the file's ``/analysis`` describes its samples as they are now: its ``samples`` attribute equals the
    length of ``/global/time`` (an analysis written before that attribute: the run was complete then as now)."""
    g = f[GROUP]
    if "samples" in g.attrs:
        return int(g.attrs["samples"]) == f["global/time"].shape[0]
    return bool(g.attrs.get("run_complete", False)) == bool(run_attr(f, "complete", False))


def stored(f: h5py.File, name: str) -> bool:
    """Whether the file holds ``/analysis/<name>`` and it still fits the samples (:func:`analysis_fits`)."""
    return f"{GROUP}/{name}" in f and analysis_fits(f)


def analysis_group(f: h5py.File, name: str, compute: Callable[[], Group | None]) -> Group | None:
    """``/analysis/<name>`` from the file when :func:`stored`, else ``compute()`` (nothing is written)."""
    if stored(f, name):
        return read_group(f[f"{GROUP}/{name}"])
    return compute()


def write_analysis(f: h5py.File, groups: dict[str, Group], attrs: dict[str, Any]) -> None:
    """Replace ``/analysis`` by ``groups``: written into a temporary group, then swapped in.

    If writing fails, the temporary group is removed and the previous ``/analysis`` is left as it was. Room for
    the groups is reserved first (:class:`~aca_warp.common.storage.GuardedFile`): a full device, a file-size limit
    or a quota raises a :class:`~aca_warp.common.errors.StorageError` before anything is written, and the file is
    closed without another write (as it was); the swap is not cut half-way by Ctrl-C or SIGTERM (one that comes during
    it, or later, is reported as not having stopped the command: :func:`~aca_warp.common.interrupts.deferred`).
    """
    from aca_warp.common.interrupts import deferred
    from aca_warp.common.storage import GuardedFile, storage_errno, storage_error

    guard = GuardedFile(f, f.filename)
    need = sum(np.asarray(d).nbytes + 4096 for g in groups.values() for d, _ in g.datasets.values())
    try:
        guard.reserve(need)
        if TMP_GROUP in f:
            del f[TMP_GROUP]
        try:
            tmp = f.create_group(TMP_GROUP)
            for k, v in attrs.items():
                tmp.attrs[k] = _attr_value(v)
            for name, group in groups.items():
                _write_group(tmp, name, group)
        except BaseException:
            try:
                if TMP_GROUP in f:
                    del f[TMP_GROUP]
            finally:
                raise
        with deferred(completes=True):  # the command's output is whole once the swap is done
            if GROUP in f:
                del f[GROUP]
            f.move(TMP_GROUP, GROUP)
            guard.flush()
    except Exception as e:  # a StorageError of the reservation, or an OSError/RuntimeError of HDF5
        code = storage_errno(e)
        if code is None:
            raise
        guard.abandon()
        raise storage_error(code, f"/analysis into {guard.path}", "the file keeps its samples as they were") from None


def _package_version() -> str:
    import importlib.metadata as md

    try:
        return md.version("aca-warp")
    except md.PackageNotFoundError:
        return "unknown"


def analyze_run(
    path: str | Path,
    *,
    freq_range: tuple[float | None, float | None] | None = None,
    sync: bool = True,
    rule: str = "relative",
    eta: float = 0.1,
    snr: float = 5.0,
    n_bins: int = 180,
    stft_window_s: float | None = None,
    cwt_freqs: Sequence[float] | np.ndarray | None = None,
    cwt_count: int = 96,
    cwt_columns: int = 2048,
    null_trials: int = 100,
    max_bytes: int = 1 << 30,
    workers: int | None = -1,
) -> dict[str, Group]:
    """Analyse a run file and (re)write its ``/analysis`` group; returns the groups written.

    The run file's output lock (``RUN.h5.lock`` and its identity, :class:`~aca_warp.common.files.OutputLock`) is
    held throughout, so a run that another process still writes or resumes is refused, and ``/analysis`` records
    the samples it describes (``samples``, ``time_range`` [s]; a resumed run drops it).

    Args:
        path: Run file written by ``aca-warp hf`` / :func:`aca_warp.hf.runner.run_scene`.
        freq_range: ``(fmin, fmax)`` [Hz] of the Synchronization Index, the CWT and the peak search; a None
            edge takes its default, 10 Hz or min(200 kHz, Nyquist). None: S(f) and the CWT use
            10 Hz – min(200 kHz, Nyquist), the peak search 1 kHz – Nyquist.
        sync: Read the per-patch velocities, when the run has them, for the Synchronization Index and the
            mean per-patch velocity spectrum (one pass, the slow part). False skips both: the velocity peak
            then comes from the Σu̇ spectrum.
        rule: Φ rule of the Synchronization Index, ``"relative"`` (|X_i| ≥ η max_j |X_j|) or ``"snr"``
            (|X_i| ≥ κ · median_f |X_i|).
        eta: η of the relative rule, in (0, 1].
        snr: κ of the SNR rule, > 0.
        n_bins: Number of phase bins on [-π, π) (paper: 180).
        stft_window_s: STFT window length [s] (default :func:`default_stft_window`).
        cwt_freqs: CWT frequencies [Hz] (default ``cwt_count`` log-spaced, see :func:`default_cwt_freqs`).
        cwt_count: Number of default CWT frequencies.
        cwt_columns: Largest number of time columns of the stored CWT map.
        null_trials: Monte-Carlo trials per Φ of the null level S_null (0: none).
        max_bytes: Memory budget of each per-patch buffer [bytes] (see ``sync_index_from_signals``).
        workers: Threads of ``scipy.fft`` (-1: all CPUs).

    Raises:
        SceneError: The file is missing, not an HDF5 run file, not writable, written by another process, or an
            option is invalid; the file is then left unchanged.
    """
    from aca_warp.common.files import locked_output

    _check_options(rule, eta, snr, n_bins)
    _check_counts(cwt_count=cwt_count, cwt_columns=cwt_columns, null_trials=null_trials)
    if stft_window_s is not None and not (_is_number(stft_window_s) and 0.0 < stft_window_s < math.inf):
        raise SceneError(f"stft_window_s must be a positive window length in s, got {stft_window_s!r}")
    eta, snr, n_bins, null_trials = float(eta), float(snr), int(n_bins), int(null_trials)
    cwt_count, cwt_columns = int(cwt_count), int(cwt_columns)
    stft_window_s = None if stft_window_s is None else float(stft_window_s)
    index = {"rule": rule, "eta": eta, "snr": snr, "n_bins": n_bins, "null_trials": null_trials}
    said = missing_run_message(path)  # first: the lock would name a folder as an output
    if said is not None:
        raise SceneError(said)
    busy = "wait for it to finish or stop it (analyze writes /analysis into the run file)"
    with locked_output(path, what=busy) as lock:
        if Path(path).is_file():  # a missing file: open_run_file's message
            lock.own(path, what=busy)
        band = _checked_band(path, freq_range)
        with open_run_file(path, "r+") as f:
            groups: dict[str, Group] = {"spectra": compute_spectra(f)}
            if sync:
                groups.update(_patch_velocity_groups(f, band, index, max_bytes, workers))
            groups["stft"] = compute_stft(f, window_s=stft_window_s)
            groups["cwt"] = compute_cwt(f, freqs=cwt_freqs, freq_range=band, count=cwt_count, columns=cwt_columns)
            groups["peaks"] = compute_peaks(groups["spectra"], groups.get("patch_spectrum"), freq_range=band)
            groups["saturation"] = compute_saturation(f)
            parameters = {
                "freq_range": list(band) if band else None,
                "sync": sync,
                "rule": rule,
                "eta": eta,
                "snr": snr,
                "n_bins": n_bins,
                "stft_window_s": stft_window_s,
                "cwt_count": cwt_count,
                "cwt_columns": cwt_columns,
                "null_trials": null_trials,
            }
            t = f["global/time"]
            attrs = {
                "created_by": "aca_warp.analysis.report.analyze_run",
                "aca_warp_version": _package_version(),
                "parameters": parameters,
                "run_complete": bool(run_attr(f, "complete", False)),
                "samples": int(t.shape[0]),
                "time_range": [float(t[0]), float(t[-1])],
                "groups": json.dumps(sorted(groups)),
            }
            write_analysis(f, groups, attrs)
    return groups


def _is_number(v: Any) -> bool:
    """A real number (Python or NumPy), not a bool."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _check_counts(**counts: Any) -> None:
    """Refuse a count option of :func:`analyze_run` that is not an integer at least its minimum (:class:`SceneError`):
    ``cwt_count`` ≥ 1 frequency, ``cwt_columns`` ≥ 2 time columns (one column is no map), ``null_trials`` ≥ 0 (0:
    no null level)."""
    least = {"cwt_count": 1, "cwt_columns": 2, "null_trials": 0}
    for name, value in counts.items():
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < least[name]:
            raise SceneError(f"{name} must be an integer >= {least[name]}, got {value!r}")


def _check_options(rule: str, eta: float, snr: float, n_bins: int) -> None:
    """Refuse a Synchronization Index option of :func:`analyze_run` that is out of range (:class:`SceneError`)."""
    if rule not in RULES:
        raise SceneError(f"rule must be one of {', '.join(RULES)}, got {rule!r}")
    if not (_is_number(eta) and 0.0 < eta <= 1.0):
        raise SceneError(f"eta must lie in (0, 1], got {eta!r}")
    if not (_is_number(snr) and 0.0 < snr < math.inf):
        raise SceneError(f"snr must be > 0, got {snr}")
    if isinstance(n_bins, bool) or not isinstance(n_bins, (int, np.integer)) or n_bins < 2:
        raise SceneError(f"n_bins must be an integer >= 2, got {n_bins!r}")


def _checked_band(path: str | Path, freq_range: tuple[float | None, float | None] | None) -> tuple[float, float] | None:
    """:func:`analyze_run`'s band [Hz]: ``freq_range`` with a None edge replaced by its default (10 Hz, or
    min(200 kHz, Nyquist)); None stays None. Opens the file read-only first, so that a file that is not a run file
    is refused before it is opened for writing."""
    with open_run_file(path, "r") as f:
        if freq_range is None:
            return None
        lo, hi = freq_range
        low = option("freq_range[0]", "--freq-min")
        lo = DEFAULT_FLOOR_HZ if lo is None else float(lo)
        nyq = 0.5 / sample_interval(f["global/time"][()])
        top = "" if hi is not None else f" (by default min({DEFAULT_BAND_TOP:g} Hz, Nyquist {nyq:g} Hz))"
        hi = min(DEFAULT_BAND_TOP, nyq) if hi is None else float(hi)
        if not (0.0 <= lo < hi and math.isfinite(hi)):
            high = option("freq_range[1]", "--freq-max")
            raise SceneError(f"the band's edges must satisfy 0 <= {low} < {high}, got {lo:g} and {hi:g} Hz{top}")
        return lo, hi


def _patch_velocity_groups(
    f: h5py.File, band: tuple[float, float] | None, index: dict[str, Any], max_bytes: int, workers: int | None
) -> dict[str, Group]:
    """``patch_spectrum`` and ``sync`` of a run with per-patch velocities (none without them); ``index``: the
    Synchronization Index keywords of :func:`compute_patch_velocity`."""
    patch, sync = compute_patch_velocity(f, freq_range=band, max_bytes=max_bytes, workers=workers, **index)
    return {name: g for name, g in (("patch_spectrum", patch), ("sync", sync)) if g is not None}
