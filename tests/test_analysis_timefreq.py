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


def test_stft_windows_lie_wholly_inside_the_record():
    """A window length whose scipy border slice would start at sample -1 (250 samples, hop 62) keeps only windows
    inside the record: the per-window linear detrend sees no zero padding, so a 72 kHz sine of amplitude 1e-3 on a
    mean of 0.5 shows ≈ 1e-3 near 72 kHz (≈ 2e-3 relative to the mean), not a false maximum at the 20 kHz bin."""
    from aca_warp.analysis.measures import stft_peak

    dt = 2.0e-7
    t = np.arange(1001) * dt
    mu = 0.5 + 1.0e-3 * np.sin(2 * np.pi * 72.0e3 * t)
    times, freqs, amp, _ = stft(mu, dt, window_s=250 * dt, detrend="linear")
    assert times[0] - 125 * dt >= -1e-15 and times[-1] - 125 * dt + 250 * dt <= t[-1] + dt * (1 + 1e-9)
    fi = np.unravel_index(int(np.argmax(amp)), amp.shape)[0]
    assert 60.0e3 <= freqs[fi] <= 80.0e3
    assert amp.max() < 1.05e-3
    p = stft_peak(t, mu, 250)
    assert p.frequency == pytest.approx(72.0e3, rel=0.01)
    assert p.amplitude == pytest.approx(2.0e-3, rel=0.05)
    _, _, amp10, _ = stft(0.5 + 1e-3 * np.sin(2 * np.pi * 1e5 * np.arange(10) * 1e-6), 1e-6, detrend="linear")
    assert amp10.max() < 1.5e-3  # the default window of a 10-sample record: no 0.075 from a padded sample


@pytest.mark.parametrize("nperseg", [16, 256, 4096])
@pytest.mark.parametrize("hop_div", [4, 2, 1])
def test_power_of_two_windows_keep_scipys_windows(nperseg, hop_div):
    """Windows of 2^k samples at hops of a quarter, a half or a whole window (the validation's stft_peaks and line
    tracks) give exactly the windows ``ShortTimeFFT``'s own border gives: their maps are unchanged."""
    from scipy.signal import ShortTimeFFT
    from scipy.signal.windows import hann

    from aca_warp.analysis.timefreq import stft_window_count

    hop = nperseg // hop_div
    for n in (2 * nperseg, 2 * nperseg + 7, 5 * nperseg + 1, 2**15 + 3):
        sft = ShortTimeFFT(hann(nperseg, sym=False), hop, fs=1.0)
        p0, p1 = sft.lower_border_end[1], sft.upper_border_begin(n)[1]
        assert stft_window_count(nperseg, hop, n) == max(0, p1 - p0)
        if p1 - p0 < 2:
            continue
        times, *_ = stft(np.ones(n), 1.0, window_s=nperseg, hop_s=hop)
        np.testing.assert_array_equal(times, sft.t(n, p0, p1))


def test_stft_refuses_windows_too_short_or_too_long():
    """Fewer than 4 samples, or no whole window in the record: one line in seconds and samples; the map's check
    also wants 2 windows (``stft`` alone accepts one, for measures of windows as long as the record)."""
    from aca_warp.analysis.timefreq import check_stft_window

    x = np.ones(1001)
    with pytest.raises(ValueError, match=r"window 2e-07 s is 1 sample at dt = 2e-07 s; at least 4 samples \(8e-07 s\)"):
        stft(x, 2e-7, window_s=2e-7)
    with pytest.raises(ValueError, match=r"longer than the record \(1001 samples, 0.0002002 s\), and a whole window"):
        stft(x, 2e-7, window_s=3e-4)
    assert stft(x, 2e-7, window_s=1001 * 2e-7)[0].size == 1
    with pytest.raises(ValueError, match=r"holds 1 window of it, and the map needs 2 windows: a window of 0.0001602 s"):
        check_stft_window(1001, 250, 1001, 2e-7)
    check_stft_window(801, 200, 1001, 2e-7)
    assert stft(x, 2e-7, window_s=801 * 2e-7)[0].size == 2


@pytest.mark.parametrize(
    "n, dt, samples",
    [
        (1001, 1e-6, 64),  # README quick start: 40 samples needed for 25 kHz, rounded up (was 32: 31.25 kHz)
        (301, 1e-6, 64),
        (5686, 5e-7, 128),
        (1001, 2e-7, 256),
        (10, 1e-6, 4),  # at most the largest power of two <= N/2
        (2**20, 1e-7, 2**14),  # N/64 alone
    ],
)
def test_default_stft_window_rounds_up_to_25_khz(n, dt, samples):
    from aca_warp.analysis.report import default_stft_window

    w = default_stft_window(n, dt)
    assert w / dt == pytest.approx(samples)
    if samples * 2 <= n and 2 * samples > 1 / (25e3 * dt):
        assert 1 / w <= 25e3 * (1 + 1e-9)
    times, *_ = stft(np.ones(n), dt, window_s=w)
    assert times.size >= 2


def test_measures_and_the_stft_need_no_pywavelets():
    """PyWavelets is imported by the CWT alone: the measures, the STFT and the validation's measures load and run
    without it (a process where importing ``pywt`` fails)."""
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['pywt'] = None\n"  # any import of pywt now raises ImportError
        "import numpy as np\n"
        "import aca_warp.analysis.measures, aca_warp.studies.validation.measures\n"
        "from aca_warp.analysis import stft, cwt_morlet\n"
        "stft(np.sin(np.arange(4096) * 0.3), 1e-6, window_s=2.56e-4, hop_s=6.4e-5)\n"
        "try:\n"
        "    cwt_morlet(np.zeros(64), 1e-6, [1e5])\n"
        "except ImportError:\n"
        "    print('cwt needs pywt')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "cwt needs pywt"
