"""Tests of aca_warp.analysis.spectra: Hann amplitude/complex spectra, frequency floor, peak finding."""

from __future__ import annotations

import numpy as np
import pytest

from aca_warp.analysis import amplitude_spectrum, complex_spectrum, drop_low_frequencies, peak

DT = 1.0e-6  # s
N = 4096
DF = 1.0 / (N * DT)  # Hz
T = np.arange(N) * DT


def test_on_bin_sinusoid_amplitude_and_mean():
    """A sinusoid on a bin shows its amplitude at its frequency and bin 0 holds the mean."""
    f0 = 300 * DF
    x = 2.5 + 0.7 * np.sin(2 * np.pi * f0 * T + 0.3)
    freq, amp = amplitude_spectrum(x, DT, normalise=None)
    assert freq.shape == amp.shape == (N // 2 + 1,)
    assert freq[300] == pytest.approx(f0)
    assert np.argmax(amp[2:]) + 2 == 300  # bin 1 carries the Hann leakage of the mean
    assert amp[300] == pytest.approx(0.7, rel=1e-12)
    assert amp[0] == pytest.approx(2.5, rel=1e-12)


def test_nyquist_bin_is_not_doubled():
    """An alternating sequence ±a (a cosine at the Nyquist frequency) has amplitude a."""
    x = 0.4 * np.cos(np.pi * np.arange(N))
    _, amp = amplitude_spectrum(x, DT, normalise=None)
    assert amp[-1] == pytest.approx(0.4, rel=1e-12)


def test_normalise_to_mean_and_2d_columns():
    """normalise="mean" divides each column by |mean|; a 2-D array equals its columns done one by one."""
    f0 = 120 * DF
    x = np.stack([-0.4 + 0.02 * np.cos(2 * np.pi * f0 * T), 3.0 + 0.3 * np.sin(2 * np.pi * f0 * T)], axis=1)
    freq, amp = amplitude_spectrum(x, DT, axis=0)
    assert amp.shape == (N // 2 + 1, 2)
    assert amp[120] == pytest.approx([0.05, 0.1], rel=1e-12)
    assert amp[0] == pytest.approx([1.0, 1.0], rel=1e-12)
    for j in range(2):
        freq_j, amp_j = amplitude_spectrum(x[:, j], DT)
        np.testing.assert_array_equal(freq_j, freq)
        np.testing.assert_allclose(amp_j, amp[:, j], rtol=1e-12, atol=1e-15)


def test_normalise_rejects_zero_mean_and_bad_option():
    """A zero-mean signal cannot be normalised to its mean, and unknown options are refused."""
    x = np.tile([0.5, -0.5], N // 2)
    with pytest.raises(ValueError, match="zero mean"):
        amplitude_spectrum(x, DT)
    with pytest.raises(ValueError, match="normalise"):
        amplitude_spectrum(x + 1.0, DT, normalise="max")


@pytest.mark.parametrize("offset", [0.1, 0.25, 0.37, 0.5])
def test_peak_interpolates_off_bin_sinusoid(offset):
    """peak() locates an off-bin sinusoid to 0.02 bin and its amplitude to 4 %, beating the raw bin."""
    f0 = (700 + offset) * DF
    x = 1.0 + 0.2 * np.sin(2 * np.pi * f0 * T + 1.1)
    freq, amp = amplitude_spectrum(x, DT, normalise=None)
    f_peak, a_peak = peak(freq, amp, fmin=10 * DF)
    assert abs(f_peak - f0) < 0.02 * DF
    assert a_peak == pytest.approx(0.2, rel=0.04)
    assert abs(a_peak - 0.2) < abs(amp.max(initial=0.0, where=freq > 10 * DF) - 0.2)


def test_peak_respects_band_and_edges():
    """peak() searches only inside [fmin, fmax] and returns the bin itself at the array edge."""
    x = 0.5 * np.sin(2 * np.pi * 100 * DF * T) + 0.1 * np.sin(2 * np.pi * 900 * DF * T)
    freq, amp = amplitude_spectrum(x, DT, normalise=None)
    f_peak, a_peak = peak(freq, amp, fmin=500 * DF, fmax=1000 * DF)
    assert f_peak == pytest.approx(900 * DF)
    assert a_peak == pytest.approx(0.1, rel=1e-9)
    f_dc, a_dc = peak(freq, amp, fmax=0.0)
    assert f_dc == 0.0 and a_dc == amp[0]
    with pytest.raises(ValueError, match="no frequency bin"):
        peak(freq, amp, fmin=1e12)


def test_complex_spectrum_amplitude_phase_dtype_and_band():
    """complex_spectrum gives a·e^{iφ} for a·cos(2πft+φ), complex64 for float32, and band = slice of full."""
    phases = np.array([0.3, -2.0, 2.9])
    x = np.stack([0.8 * np.cos(2 * np.pi * 250 * DF * T + p) for p in phases], axis=1)
    freq, X = complex_spectrum(x, DT)
    assert X.dtype == np.complex128 and X.shape == (N // 2 + 1, 3)
    np.testing.assert_allclose(X[250], 0.8 * np.exp(1j * phases), rtol=1e-12)
    band_freq, band = complex_spectrum(x.astype(np.float32), DT, freq_range=(200 * DF, 300 * DF))
    assert band.dtype == np.complex64 and band.flags.c_contiguous
    np.testing.assert_array_equal(band_freq, freq[200:301])
    np.testing.assert_allclose(band, X[200:301], rtol=0, atol=2e-6)
    with pytest.raises(ValueError, match="freq_range"):
        complex_spectrum(x, DT, freq_range=(1e9, 2e9))


def test_complex_spectrum_is_column_chunkable():
    """Transforming patch columns in chunks gives the same spectra as all columns at once."""
    x = np.random.default_rng(0).standard_normal((N, 10)).astype(np.float32)
    _, whole = complex_spectrum(x, DT)
    parts = np.concatenate([complex_spectrum(x[:, j : j + 3], DT)[1] for j in range(0, 10, 3)], axis=1)
    np.testing.assert_allclose(parts, whole, rtol=0, atol=1e-6)


def test_drop_low_frequencies():
    """drop_low_frequencies removes exactly the bins below the floor, along the chosen axis."""
    freq = np.arange(0.0, 50.0, 2.5)
    values = np.arange(3 * freq.size).reshape(freq.size, 3)
    kept_freq, kept = drop_low_frequencies(freq, values, axis=0)
    assert kept_freq[0] == 10.0 and kept_freq.size == freq.size - 4
    np.testing.assert_array_equal(kept, values[4:])
    assert drop_low_frequencies(freq, freq, fmin=40.0)[1].tolist() == [40.0, 42.5, 45.0, 47.5]
