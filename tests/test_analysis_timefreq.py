"""Tests of aca_warp.analysis.timefreq: amplitude-true STFT and complex-Morlet CWT."""

from __future__ import annotations

import numpy as np
import pytest

from aca_warp.analysis import cwt_morlet, stft

DT = 1.0e-6  # s
N = 2**15
T = np.arange(N) * DT


def test_stft_shows_sinusoid_amplitude_at_its_frequency():
    """An on-bin sinusoid shows its amplitude at its frequency in every window; only full windows are kept."""
    nperseg = 1024
    f0 = 48 / (nperseg * DT)
    x = 0.3 + 0.05 * np.sin(2 * np.pi * f0 * T + 0.2)
    times, freqs, amp, info = stft(x, DT, window_s=nperseg * DT, hop_s=256 * DT)
    assert amp.shape == (freqs.size, times.size)
    k = np.argmin(np.abs(freqs - f0))
    assert freqs[k] == pytest.approx(f0)
    np.testing.assert_allclose(amp[k], 0.05, rtol=1e-9)
    assert times[0] >= nperseg / 2 * DT and times[-1] <= T[-1] - (nperseg / 2 - 1) * DT
    assert np.allclose(np.diff(times), 256 * DT)
    assert freqs[0] >= 10.0
    assert "1024 samples" in info["caption"] and "amplitude" in info["quantity"]


def test_stft_defaults_floor_and_detrend():
    """Default window and hop fit the record, fmin drops bins, and detrending removes the mean's leakage."""
    f0 = 40 / (512 * DT)
    x = 0.4 + 0.004 * np.sin(2 * np.pi * f0 * T)
    times, freqs, amp, info = stft(x, DT)
    assert freqs[1] - freqs[0] == pytest.approx(1 / (512 * DT))
    assert times.size > 100
    assert float(info["peak"].split()[0]) == pytest.approx(0.4, rel=1e-3)  # mean leaking into the first bin
    _, freqs_d, amp_d, info_d = stft(x, DT, detrend="constant", fmin=2e4)
    assert freqs_d[0] >= 2e4
    assert float(info_d["peak"].split()[0]) == pytest.approx(0.004, rel=1e-6)
    assert info_d["detrend"].startswith("constant")
    with pytest.raises(ValueError, match="window"):
        stft(x[:100], DT, window_s=200 * DT)


@pytest.mark.parametrize("f0", [200.0, 3333.3, 47_000.0])
def test_cwt_amplitude_true(f0):
    """A stationary sinusoid of amplitude a gives |W| = a (within 5 %) at its frequency, away from the edges."""
    x = 1.5 + 0.05 * np.sin(2 * np.pi * f0 * T + 0.4)
    freqs = np.array([0.7 * f0, f0, 1.4 * f0])
    times, out_freqs, W, info = cwt_morlet(x, DT, freqs)
    assert W.shape == (3, N) and times.shape == (N,)
    np.testing.assert_array_equal(out_freqs, freqs)
    edge = int(3 / (f0 * DT))
    inner = W[:, edge : N - edge] if N > 2 * edge + 10 else W[:, N // 2 - 5 : N // 2 + 5]
    np.testing.assert_allclose(inner[1], 0.05, rtol=0.05)
    assert inner[0].max() < 0.7 * 0.05 and inner[2].max() < 0.7 * 0.05
    assert "L1" in info["normalisation"] and "cmor1.5-1.0" in info["caption"]


def test_cwt_dtype_complex_and_stride():
    """float32 input gives float32 |W| (complex64 W), the stride decimates times, and |W| = abs(complex W)."""
    f0 = 10_000.0
    x = (0.2 * np.cos(2 * np.pi * f0 * T)).astype(np.float32)
    freqs = np.geomspace(2e3, 1e5, 11)
    times, _, mag, _ = cwt_morlet(x, DT, freqs, stride=7, chunk=4)
    _, _, W, _ = cwt_morlet(x, DT, freqs, stride=7, complex_output=True)
    assert mag.dtype == np.float32 and W.dtype == np.complex64
    assert mag.shape == (11, -(-N // 7)) and times[1] == pytest.approx(7 * DT)
    np.testing.assert_allclose(mag, np.abs(W), rtol=1e-5, atol=1e-7)
    k = np.argmin(np.abs(freqs - f0))
    assert np.argmax(mag[:, N // 14]) == k
    with pytest.raises(ValueError, match="frequencies"):
        cwt_morlet(x, DT, np.array([1e3, 6e5]))
