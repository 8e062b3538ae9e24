"""Measures for the paper's statements (aca_warp/analysis/measures/), each on a signal with a known answer."""

from __future__ import annotations

import numpy as np
import pytest

from aca_warp.analysis.measures import (
    PrevalenceTable,
    averaged_spectrum,
    ensemble_interval,
    equal_prevalence_difference,
    first_peak,
    line_trend,
    neighbour_coherence,
    peak_to_floor,
    peak_track,
    peak_width,
    phase_correlation_length,
    plateau_excess,
    prevalence_classes,
    shared_peak_fraction,
    shared_peaks,
    spectral_agreement,
    spectral_overlap,
    stft_peak,
    stft_peaks,
    sync_by_prevalence,
    tonality,
)
from aca_warp.analysis.spectra import amplitude_spectrum
from aca_warp.analysis.timefreq import stft

# ---------------------------------------------------------------------------------------------- peak width


def lorentz(f: np.ndarray, f0: float, gamma: float) -> np.ndarray:
    """Amplitude response of a resonance: 1/√(1 + ((f − f0)/γ)²)."""
    return 1.0 / np.sqrt(1.0 + ((f - f0) / gamma) ** 2)


def test_peak_width_of_a_hann_sinusoid_is_two_bins():
    dt, n, k = 1e-6, 4096, 300
    t = np.arange(n) * dt
    freq, amp = amplitude_spectrum(2.5 * np.sin(2 * np.pi * k / (n * dt) * t), dt, normalise=None)
    w = peak_width(freq, amp, k / (n * dt) + 40.0)
    df = freq[1]
    assert w.frequency == pytest.approx(k * df, abs=1e-6 * df)
    assert w.height == pytest.approx(2.5, rel=1e-9)
    assert w.width == pytest.approx(2.0 * df, rel=1e-9)  # Hann main lobe: 1, 1/2, 0 at 0, ±1, ±2 bins
    assert w.f_low == pytest.approx((k - 1) * df, rel=1e-9)
    assert w.relative_prominence == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize(("rel_height", "factor"), [(0.5, 2 * np.sqrt(3.0)), (1 / np.sqrt(2.0), 2.0)])
def test_peak_width_of_a_resonance(rel_height, factor):
    freq = np.arange(0.0, 200e3, 10.0)
    gamma = 1.5e3
    amp = 3.0 * lorentz(freq, 73e3, gamma) + 0.01
    w = peak_width(freq, amp, 73.02e3, search=200.0, rel_height=rel_height)
    level = rel_height * 3.01  # the floor adds 0.01 to the height; solve 3 L(f) + 0.01 = level for the width
    half = gamma * np.sqrt((3.0 / (level - 0.01)) ** 2 - 1.0)
    assert w.width == pytest.approx(2 * half, rel=1e-3)
    assert w.width == pytest.approx(factor * gamma, rel=0.02)
    assert w.frequency == pytest.approx(73e3, abs=0.5)
    narrow = peak_width(freq, 3.0 * lorentz(freq, 73e3, gamma / 2) + 0.01, 73e3, rel_height=rel_height)
    assert narrow.width == pytest.approx(w.width / 2, rel=0.02)


def test_peak_width_without_a_crossing_is_nan():
    freq = np.arange(0.0, 10e3, 10.0)
    amp = lorentz(freq, 100.0, 500.0)  # the lower half-maximum crossing would lie below 0 Hz
    w = peak_width(freq, amp, 100.0)
    assert np.isnan(w.f_low) and np.isnan(w.width) and np.isfinite(w.f_high)
    with pytest.raises(ValueError, match="rel_height"):
        peak_width(freq, amp, 100.0, rel_height=1.0)


# ------------------------------------------------------------------------------------------ spectral overlap


def test_spectral_overlap():
    rng = np.random.default_rng(0)
    freq = np.arange(0.0, 1e5, 25.0)
    a = rng.lognormal(size=freq.size)
    o = spectral_overlap(freq, a, 1.1 * a)
    assert o.mean_abs_log == pytest.approx(np.log(1.1)) and o.mean_log_ratio == pytest.approx(-np.log(1.1))
    assert o.bins == np.count_nonzero(freq >= 10.0) and o.band == (10.0, freq[-1])
    assert spectral_overlap(freq, a, a).mean_abs_log == 0.0
    b = a.copy()
    b[freq > 5e4] *= 2.0  # differ in the upper half only
    o = spectral_overlap(freq, a, b, band=(0.0, 5e4))
    assert o.mean_abs_log == 0.0
    o = spectral_overlap(freq, a, b)
    assert o.mean_abs_log == pytest.approx(np.log(2.0) * np.mean(freq[freq >= 10.0] > 5e4))
    assert o.max_abs_log == pytest.approx(np.log(2.0))
    b[:] = 0.0
    with pytest.raises(ValueError, match="both spectra are positive"):
        spectral_overlap(freq, a, b)


# -------------------------------------------------------------------------------------------- shared peaks


def test_shared_peaks():
    freq = np.arange(0.0, 200e3, 100.0)
    floor = 1e-4 / (1.0 + freq / 1e4)

    def spec(peaks):
        return floor + sum(h * lorentz(freq, f, 150.0) * 1e-3 for f, h in peaks)

    spectra = {
        "mu": spec([(20e3, 1.0), (73e3, 3.0), (110e3, 0.5)]),
        "torque": spec([(20.1e3, 1.0), (25e3, 0.15), (73e3, 2.0), (150e3, 1.0)]),
        "friction_radius": spec([(19.9e3, 1.5), (73.1e3, 1.0), (110e3, 1.0)]),
    }
    common = shared_peaks(freq, spectra)
    assert [round(p.frequency, -2) for p in common] == [20e3, 73e3]
    assert set(common[1].members) == set(spectra)
    assert common[1].members["mu"][0] == 73e3
    two = shared_peaks(freq, spectra, min_count=2)
    assert [round(p.frequency, -2) for p in two] == [20e3, 73e3, 110e3]
    assert set(two[2].members) == {"mu", "friction_radius"}
    assert shared_peaks(freq, spectra, tolerance=50.0) == []  # 100 Hz apart: never grouped
    wide = shared_peaks(freq, spectra, tolerance=5.5e3, prominence=2.0)  # torque's 25 kHz peak joins the 20 kHz group
    assert wide[0].members["torque"] == (20.1e3, pytest.approx(spectra["torque"][201]))  # the larger one
    assert 25e3 not in [f for f, _ in wide[0].members.values()]
    assert all(p.frequency != 25e3 for p in shared_peaks(freq, spectra, min_count=1))  # < 4x its surroundings
    assert len(shared_peaks(freq, spectra, prominence=1e3)) == 0  # no peak stands 1000x above its surroundings


# ------------------------------------------------------------------------------------ phase correlation length


def test_phase_random_walk_along_a_line_has_its_exact_length():
    """φ(x) a Brownian path with Var(φ(x) − φ(x + d)) = 2d/ℓ: E cos(Δφ) = exp(−d/ℓ) exactly."""
    rng = np.random.default_rng(1)
    n, dx, ell = 1000, 5e-5, 5e-3
    x = np.arange(n) * dx
    phase = np.cumsum(rng.normal(0.0, np.sqrt(2 * dx / ell), (20, n)), axis=1)
    r = phase_correlation_length(x, np.zeros(n), phase, max_distance=3 * ell, bins=15)
    assert r.length == pytest.approx(ell, rel=0.1)
    assert r.length_e == pytest.approx(ell, rel=0.1)
    assert r.fit_rms < 0.05
    np.testing.assert_allclose(r.correlation, np.exp(-r.distance / ell), atol=0.08)


def test_gaussian_phase_field_in_two_dimensions():
    """φ a Gaussian field, covariance s² exp(−d²/2λ²): E cos(Δφ) = exp(−s²(1 − exp(−d²/2λ²)))."""
    rng = np.random.default_rng(2)
    n, s2, lam = 500, 2.0, 3e-3
    x, y = rng.uniform(0, 0.03, n), rng.uniform(0, 0.03, n)
    d = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    chol = np.linalg.cholesky(s2 * np.exp(-(d**2) / (2 * lam**2)) + 1e-9 * np.eye(n))
    phase = (chol @ rng.standard_normal((n, 40))).T
    r = phase_correlation_length(x, y, phase, max_distance=0.012, bins=24)
    d_e = lam * np.sqrt(-2.0 * np.log(1.0 - 1.0 / s2))  # 1/e distance of the exact curve: 3.53 mm
    assert r.length_e == pytest.approx(d_e, rel=0.1)
    exact = np.exp(-s2 * (1 - np.exp(-(r.distance**2) / (2 * lam**2))))
    np.testing.assert_allclose(r.correlation, exact, atol=0.1)


def test_random_and_uniform_phases_and_amplitude_weights():
    rng = np.random.default_rng(3)
    n = 400
    x, y = rng.uniform(0, 0.02, n), rng.uniform(0, 0.02, n)
    random = phase_correlation_length(x, y, rng.uniform(-np.pi, np.pi, (10, n)))
    assert random.length < 0.25 * random.distance[0] and random.length_e == 0.0  # 0 within the bins' resolution
    assert np.all(np.abs(random.correlation) < 0.05)
    uniform = phase_correlation_length(x, y, np.full(n, 0.7))
    assert uniform.length == np.inf and uniform.length_e == np.inf
    # patches that do not move (amplitude 0) with random phases do not change C(d)
    half = np.arange(n) < n // 2
    phase = np.where(half, 0.3 + 0.1 * rng.standard_normal(n), rng.uniform(-np.pi, np.pi, n))
    weighted = phase_correlation_length(x, y, phase, amplitude=half.astype(float), max_distance=0.01, bins=5)
    alone = phase_correlation_length(x[half], y[half], phase[half], max_distance=0.01, bins=5)
    np.testing.assert_allclose(weighted.correlation, alone.correlation, rtol=1e-12)
    with pytest.raises(ValueError, match="finite"):
        phase_correlation_length(x, y, np.full(n, np.nan))


# ------------------------------------------------------------------------------------------- STFT measures

DT = 1e-7  # s: 10 MHz sampling, as hf1 records at 0.1 µs


def test_stft_peak_amplitude_frequency_and_time():
    n, w, k = 2**16, 4096, 283
    t = np.arange(n) * DT
    f = k / (w * DT)  # on a bin of the 4096-sample window: 69.09 kHz
    ramp = 0.5 + 0.5 * t / t[-1]
    mu = 0.4 + 0.004 * ramp * np.sin(2 * np.pi * f * t) + 0.05 * t / t[-1]  # slow drift of the mean
    p = stft_peak(t, mu, w)
    centres = stft(mu, DT, window_s=w * DT, hop_s=w // 4 * DT)[0]
    assert p.time == pytest.approx(centres[-1], abs=DT / 2)  # the largest amplitude: the last window
    mean = np.mean(mu)
    assert p.amplitude == pytest.approx(0.004 * (0.5 + 0.5 * p.time / t[-1]) / mean, rel=1e-3)
    assert p.frequency == pytest.approx(f, abs=1e-3 * p.resolution)
    assert "Hann" in p.window and p.window_samples == w and p.hop_samples == w // 4
    local = stft_peak(t, mu, w, normalise="window")
    start = round(local.time / DT) - w // 2
    assert local.mean == pytest.approx(np.mean(mu[start : start + w]), rel=1e-12)
    assert local.amplitude == pytest.approx(p.amplitude * mean / local.mean, rel=1e-9)
    assert [q.window_samples for q in stft_peaks(t, mu)] == [2**12, 2**13, 2**14, 2**15, 2**16]
    with pytest.raises(ValueError, match="normalise"):
        stft_peak(t, mu, w, normalise="max")


def test_falling_line_from_the_stft_of_a_chirp():
    n, w = 2**17, 2048
    t = np.arange(n) * DT
    rate = -2.0e6  # Hz/s: 73 kHz → 46.8 kHz over the 13.1 ms record
    phase = 2 * np.pi * (73e3 * t + 0.5 * rate * t**2)
    mu = 0.4 + 0.004 * np.sin(phase)
    times, freqs, amp, _ = stft(mu, DT, window_s=w * DT, hop_s=w * DT, detrend="linear")  # no overlap
    f_line, _ = peak_track(times, freqs, amp, band=(20e3, 100e3))
    trend = line_trend(times, f_line)
    assert trend.slope_low < rate < trend.slope_high
    assert trend.slope == pytest.approx(rate, rel=0.02)
    assert trend.falling and trend.r2 > 0.99
    assert trend.intercept == pytest.approx(73e3, rel=0.01)


def test_line_trend_interval_covers_the_true_slope_at_its_level():
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 1.0, 12)
    hits = []
    for _ in range(2000):
        f = 70e3 - 500.0 * t + rng.normal(0.0, 100.0, t.size)
        r = line_trend(t, f)
        hits.append(r.slope_low <= -500.0 <= r.slope_high)
    assert 0.94 <= np.mean(hits) <= 0.96  # 2000 trials: binomial standard deviation 0.005
    f = 70e3 - 500.0 * t
    f[3] = np.nan
    r = line_trend(t, f)
    assert r.n == 11 and r.slope == pytest.approx(-500.0) and r.stderr < 1e-4
    with pytest.raises(ValueError, match="3 finite points"):
        line_trend(t[:2], f[:2])


def test_ensemble_interval():
    rng = np.random.default_rng(5)
    values = rng.normal(3.0, 2.0, (5, 4000))  # 4000 ensembles of 5 seeds
    e = ensemble_interval(values)
    covered = (e.mean_low <= 3.0) & (3.0 <= e.mean_high)
    assert 0.94 <= covered.mean() <= 0.96  # binomial standard deviation 0.0034
    one = ensemble_interval(np.arange(101.0))
    assert one.mean == 50.0 and one.median == 50.0 and one.n == 101
    assert (one.low, one.high) == pytest.approx((2.5, 97.5))
    half = 1.984 * np.std(np.arange(101.0), ddof=1) / np.sqrt(101)  # t_{0.975, 100} = 1.984
    assert one.mean_high - one.mean == pytest.approx(half, rel=1e-3)
    single = ensemble_interval([4.2])
    assert single.mean == 4.2 and np.isnan(single.mean_low) and np.isnan(single.std)
    with pytest.raises(ValueError, match="finite"):
        ensemble_interval([1.0, np.nan])


# ------------------------------------------------------------------------------ peak contrast and plateaus


def test_first_peak_is_the_lowest_peak_reaching_the_fraction():
    freq = np.arange(0.0, 200e3, 100.0)
    amp = 1e-3 + 0.6 * lorentz(freq, 72e3, 300.0) + 1.0 * lorentz(freq, 95e3, 300.0) + 0.3 * lorentz(freq, 50e3, 300.0)
    f, a = first_peak(freq, amp, fmin=1e3)
    assert f == pytest.approx(72e3, abs=20.0) and a == pytest.approx(amp[720], rel=1e-6)  # 50 kHz: below half the max
    assert first_peak(freq, amp, fraction=0.25, fmin=1e3)[0] == pytest.approx(50e3, abs=20.0)
    assert first_peak(freq, amp, fraction=0.9)[0] == pytest.approx(95e3, abs=20.0)  # only the largest reaches 0.9
    assert first_peak(freq, amp, fmin=80e3)[0] == pytest.approx(95e3, abs=20.0)
    with pytest.raises(ValueError, match="fraction"):
        first_peak(freq, amp, fraction=0.0)


def test_peak_to_floor_is_height_over_the_median_of_its_octaves():
    freq = np.arange(0.0, 200e3, 50.0)
    amp = np.full(freq.size, 2.0)
    amp[(freq > 36e3) & (freq < 40e3)] = 1.0  # a dip inside the floor band moves the median, not the peak
    amp[1460] = 30.0  # 73 kHz
    c = peak_to_floor(freq, amp, 73.04e3)
    assert c.frequency == 73e3 and c.height == 30.0
    band = (freq >= 0.5 * 73.04e3) & (freq <= 2 * 73.04e3)
    assert c.floor == np.median(amp[band]) == 2.0
    assert c.ratio == 15.0 and c.floor_band == (0.5 * 73.04e3, 2 * 73.04e3)
    assert peak_to_floor(freq, 7.0 * amp, 73e3).ratio == pytest.approx(15.0)  # independent of normalisation
    assert peak_to_floor(freq, amp, 60e3).height == 2.0  # no peak within 2 bins of 60 kHz
    with pytest.raises(ValueError, match="floor band"):
        peak_to_floor(freq, amp, 150e3, floor_band=(1.5, 2.0))


def test_plateau_excess_of_piecewise_levels():
    freq = np.arange(0.0, 400e3, 50.0)
    f0 = 50e3
    amp = np.where(freq < 1.5 * f0, 1.0, np.where(freq <= 2 * f0, 0.5, 0.125))
    p = plateau_excess(freq, amp, f0, near=(1.6, 2.0), far=(2.5, 4.0))
    assert p.excess == pytest.approx(np.log(4.0)) and p.near_level == 0.5 and p.far_level == 0.125
    assert plateau_excess(freq, np.ones(freq.size), f0).excess == 0.0
    falling = 1.0 / freq[1:]  # a 1/f spectrum: the excess is the log ratio of the bands' median frequencies
    p = plateau_excess(freq[1:], falling, f0)
    assert p.excess == pytest.approx(np.log(np.median([2.5, 4.0]) / np.median([1.1, 2.0])), rel=1e-3)


def test_shared_peak_fraction_and_its_chance_level():
    freq = np.arange(0.0, 100e3, 100.0)
    base = np.ones(freq.size)

    def spec(peaks):
        a = base.copy()
        a[peaks] = 10.0
        return a

    mu = spec([100, 200, 300, 400])
    torque = spec([100, 201, 300, 600, 700])
    radius = spec([101, 199, 500])
    s = shared_peak_fraction(freq, {"mu": mu, "torque": torque, "friction_radius": radius}, "mu", band=(1e3, 1e5))
    assert (s.shared, s.reference_peaks, s.fraction) == (2, 4, 0.5)  # 10 kHz and 20 kHz are in all three
    bins = np.count_nonzero(freq >= 1e3)
    assert s.chance == pytest.approx((5 * 5 / bins) * (3 * 5 / bins))  # ±2 bins: 5 bins per peak
    with pytest.raises(ValueError, match="reference"):
        shared_peak_fraction(freq, {"a": mu, "b": torque}, "mu")
    assert np.isnan(shared_peak_fraction(freq, {"mu": base, "torque": torque}, "mu").fraction)


# ----------------------------------------------------------------------------- synchronisation at equal Φ


def test_sync_by_prevalence_matches_a_direct_average():
    rng = np.random.default_rng(3)
    phi = rng.integers(0, 300, 5000)
    S = rng.random(5000)
    null = rng.random(5000) * 0.5
    S[:50] = np.nan  # undefined bins are left out
    t = sync_by_prevalence(S, null, phi)
    assert list(t.lower) == [2, 4, 8, 16, 32, 64, 128, 256] and t.upper[-1] == 512
    assert list(prevalence_classes(255)) == [2, 4, 8, 16, 32, 64, 128, 256]
    for k, (lo, hi) in enumerate(zip(t.lower, t.upper, strict=True)):
        sel = (phi >= lo) & (phi < hi) & np.isfinite(S)
        assert t.bins[k] == sel.sum()
        assert t.mean_S[k] == pytest.approx(S[sel].mean())
        assert t.mean_excess[k] == pytest.approx((S[sel] - null[sel]).mean())
    assert t.bins.sum() == np.count_nonzero((phi >= 2) & np.isfinite(S))
    fixed = sync_by_prevalence(S, null, phi, edges=np.array([2, 10, 1000]))
    assert fixed.bins.sum() == t.bins.sum() and np.isnan(sync_by_prevalence(S, null, 0 * phi, edges=[2, 4]).mean_S[0])


def _table(lower, bins, excess, s):
    lower = np.asarray(lower)
    n = len(lower)
    return PrevalenceTable(lower, 2 * lower, np.asarray(bins), np.asarray(s, float), np.zeros(n), np.asarray(excess))


def test_equal_prevalence_difference_uses_the_classes_every_record_populates():
    edges = [2, 4, 8, 16]
    a = [_table(edges, [50, 50, 50, 5], [0.3, 0.5, 0.7, 9.0], [0.9, 0.8, 0.7, 0.0]) for _ in range(2)]
    b = [
        _table(edges, [50, 50, 50, 50], [0.1, 0.2, 0.3, 0.0], [0.1, 0.1, 0.1, 0.1]),
        _table(edges, [0, 50, 50, 50], [0.0, 0.1, 0.1, 0.0], [0.0, 0.0, 0.0, 0.0]),
    ]
    d = equal_prevalence_difference(a, b)  # class 0 empty in b[1], class 3 sparse in a: classes 1, 2 only
    assert list(d.classes) == [False, True, True, False]
    assert d.difference == pytest.approx([np.mean([0.3, 0.4]), np.mean([0.4, 0.6])])
    assert d.reference == pytest.approx([0.25, 0.1])  # b's own mean over the same classes: a's is b's + difference
    raw = equal_prevalence_difference(a, b, value="S")
    assert raw.difference == pytest.approx([np.mean([0.7, 0.6]), np.mean([0.8, 0.7])])
    none = equal_prevalence_difference(a, b, min_bins=1000)
    assert not none.classes.any() and np.all(np.isnan(none.difference)) and np.all(np.isnan(none.reference))
    with pytest.raises(ValueError, match="equal size"):
        equal_prevalence_difference(a, b[:1])


def test_spectral_agreement_is_a_rank_correlation_over_the_band():
    from scipy.stats import spearmanr

    freq = np.arange(0.0, 100e3, 100.0)
    rng = np.random.default_rng(4)
    amp = rng.lognormal(size=freq.size)
    S = np.full(freq.size, 0.5)
    phi = 2 + np.argsort(np.argsort(amp))  # S·Φ a strictly increasing function of amp
    assert spectral_agreement(freq, S, phi, amp) == pytest.approx(1.0)
    assert spectral_agreement(freq, S, phi, 1.0 / amp) == pytest.approx(-1.0)
    S2 = rng.random(freq.size)
    S2[::7] = np.nan  # undefined: no synchronised patches, S·Φ = 0
    band = (freq >= 20e3) & (freq <= 80e3)
    ref = spearmanr(np.nan_to_num(S2[band]) * phi[band], amp[band]).statistic
    assert spectral_agreement(freq, S2, phi, amp) == pytest.approx(ref)
    assert abs(spectral_agreement(freq, S2, rng.integers(2, 50, freq.size), amp)) < 0.1
    assert np.isnan(spectral_agreement(freq, S, np.ones(freq.size), amp))


def test_tonality_of_a_line_over_noise_and_of_white_noise():
    rng = np.random.default_rng(3)
    dt, n = 1e-6, 2**14
    t = np.arange(n) * dt
    noise = rng.normal(0.0, 1.0, n)
    f, a = amplitude_spectrum(noise, dt, normalise=None)
    white = tonality(f, a, band=(5e3, 150e3))
    # |X| of white noise is Rayleigh: power exponential, flatness = exp(E ln P)/E P = exp(−γ) ≈ 0.561
    assert white.flatness == pytest.approx(np.exp(-np.euler_gamma), abs=0.03)
    assert white.peak_to_median < 2.0
    f0 = 2**9 / (n * dt)  # on a bin
    f, a = amplitude_spectrum(noise + 5.0 * np.sin(2 * np.pi * f0 * t), dt, normalise=None)
    line = tonality(f, a, band=(5e3, 150e3))
    assert line.peak_frequency == pytest.approx(f0)
    med = np.median(a[(f >= 5e3) & (f <= 150e3)])
    assert line.peak_to_median == pytest.approx(np.log(a[np.argmin(np.abs(f - f0))] / med))
    assert line.flatness < white.flatness and line.peak_to_median > white.peak_to_median + 2.0
    with pytest.raises(ValueError, match="no frequency bin"):
        tonality(f, a, band=(1e9, 2e9))


def test_neighbour_coherence_matches_a_pairwise_sum():
    rng = np.random.default_rng(4)
    n, bins, radius = 120, 6, 2.5e-3
    x, y = rng.uniform(0, 0.02, n), rng.uniform(0, 0.02, n)
    X = rng.uniform(0.1, 1.0, (bins, n)) * np.exp(1j * rng.uniform(-np.pi, np.pi, (bins, n)))
    X[0] = rng.uniform(0.1, 1.0, n) * np.exp(0.7j)  # every patch in phase: C = 1
    X[1] = np.where(x < 0.01, 1.0, -1.0) * rng.uniform(0.1, 1.0, n)  # two antiphase halves: C < 1
    d = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    i, j = np.nonzero(np.triu(d <= radius, 1))
    ref = np.real(np.sum(X[:, i] * np.conj(X[:, j]), axis=1)) / np.sum(np.abs(X[:, i] * X[:, j]), axis=1)
    c = neighbour_coherence(x, y, X, radius)
    np.testing.assert_allclose(c, ref, rtol=1e-12)
    assert c[0] == pytest.approx(1.0) and 0.0 < c[1] < 1.0
    with pytest.raises(ValueError, match="no pair"):
        neighbour_coherence(np.array([0.0, 1.0]), np.array([0.0, 0.0]), np.ones((2, 2)), 0.1)


def test_averaged_spectrum_keeps_the_amplitude_and_calms_the_scatter():
    """A sinusoid on a bin of the segment grid shows its amplitude; white noise scatters far less across bins than
    in one periodogram (the average of 7 segments)."""
    dt, n = 1e-6, 8192
    t = np.arange(n) * dt
    f0 = 100 / (n // 4 * dt)  # bin 100 of the quarter-length segments
    freq, amp = averaged_spectrum(1.5 * np.sin(2 * np.pi * f0 * t), dt, segments=4)
    assert freq[1] == pytest.approx(1 / (n // 4 * dt))
    assert freq[int(np.argmax(amp))] == pytest.approx(f0) and amp.max() == pytest.approx(1.5, rel=1e-6)
    noise = np.random.default_rng(0).normal(size=n)
    _, one = amplitude_spectrum(noise, dt, normalise=None)
    _, avg = averaged_spectrum(noise, dt, segments=4)
    assert np.std(avg[5:-5]) / np.mean(avg[5:-5]) < 0.6 * np.std(one[5:-5]) / np.mean(one[5:-5])
    with pytest.raises(ValueError, match="no segment"):
        averaged_spectrum(noise[:5], dt, segments=4)
