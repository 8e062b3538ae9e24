"""Tests of aca_warp.analysis.sync: the Synchronization Index (paper Eqs. 5-9, Appendix) and its pipeline."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aca_warp.analysis import (
    complex_spectrum,
    sync,
    sync_index,
    sync_index_from_bins,
    sync_index_from_signals,
    sync_null_level,
)
from aca_warp.analysis.sync import SMOOTHING_WEIGHTS

BIN = 2 * np.pi / 180  # rad

# Paper Table A.1 (bins) and Table A.2 (n_AB, n_AB,max, n_AB,min, n_BC, n_BC,max, n_BC,min, S_AB, S_BC, S).
APPENDIX = {
    1: ([100, 0, 0, 0, 0, 0, 0, 0, 0, 0], (0.500, 5.000, 0.500, 0.550, 5.500, 0.550, 1.000, 1.000, 1.000)),
    2: ([75, 3, 3, 3, 3, 3, 3, 3, 2, 2], (0.667, 5.000, 0.500, 0.733, 5.500, 0.550, 0.963, 0.963, 0.963)),
    3: ([27, 25, 23, 4, 4, 4, 4, 3, 3, 3], (1.920, 5.000, 0.500, 2.130, 5.500, 0.550, 0.684, 0.681, 0.684)),
    4: ([10] * 10, (5.000, 5.000, 0.500, 5.500, 5.500, 0.550, 0.000, 0.000, 0.000)),
}


def _table_row(res):
    return (res.n_AB, res.n_AB_max, res.n_AB_min, res.n_BC, res.n_BC_max, res.n_BC_min, res.S_AB, res.S_BC, res.S)


@pytest.mark.parametrize("case", sorted(APPENDIX))
def test_appendix_table_a2(case):
    """The four Appendix cases (10 bins, no filter, Φ = 100) reproduce Table A.2 to its 3 decimals."""
    bins, expected = APPENDIX[case]
    res = sync_index_from_bins(np.array(bins), smooth=False)
    assert [round(float(v), 3) + 0.0 for v in _table_row(res)] == list(expected)


def test_appendix_vectorised_and_bin_order():
    """A 2-D stack of the Appendix cases, with bins in any order, gives the same values as one case at a time."""
    rng = np.random.default_rng(1)
    stack = np.array([rng.permutation(APPENDIX[c][0]) for c in sorted(APPENDIX)])
    res = sync_index_from_bins(stack, smooth=False)
    assert res.S.shape == (4,)
    for i, case in enumerate(sorted(APPENDIX)):
        one = sync_index_from_bins(np.array(APPENDIX[case][0]), smooth=False)
        assert res.S[i] == pytest.approx(one.S, abs=1e-12)
        assert res.n_BC[i] == pytest.approx(one.n_BC, abs=1e-12)


def test_180_bin_bounds_with_filter():
    """With 180 bins and the 3-bin Gaussian filter: n_max = 90 / 99, n_min = 1 + (τ - 0.4519)/0.2741."""
    edge, centre, edge2 = SMOOTHING_WEIGHTS
    assert edge == edge2 and edge + centre + edge2 == pytest.approx(1.0)
    assert edge / centre == pytest.approx(np.exp(-0.5))
    assert (round(edge, 3), round(centre, 3)) == (0.274, 0.452)
    G = np.zeros(180)
    G[17] = 250
    res = sync_index_from_bins(G)
    assert res.n_AB_max == pytest.approx(90.0) and res.n_BC_max == pytest.approx(99.0)
    assert res.n_AB_min == pytest.approx(1 + (0.5 - centre) / edge, rel=1e-12)
    assert res.n_BC_min == pytest.approx(1 + (0.55 - centre) / edge, rel=1e-12)
    assert res.n_AB_min == pytest.approx(1.175639, abs=1e-6)
    assert res.n_BC_min == pytest.approx(1.358075, abs=1e-6)
    assert res.S == pytest.approx(1.0, abs=1e-12)


def test_filter_is_circular():
    """All phases in the last bin and all in the first bin give identical results (the filter wraps)."""
    first, last = np.zeros(180), np.zeros(180)
    first[0], last[-1] = 40, 40
    a, b = sync_index_from_bins(first), sync_index_from_bins(last)
    assert a.S == b.S == pytest.approx(1.0, abs=1e-12)
    two = np.zeros(180)
    two[[0, -1]] = 20  # adjacent across the wrap: as close as bins 5 and 6
    mid = np.zeros(180)
    mid[[5, 6]] = 20
    assert sync_index_from_bins(two).S == pytest.approx(sync_index_from_bins(mid).S, abs=1e-12)
    assert sync_index_from_bins(two).S < 1.0


def test_fewer_than_two_phases_is_nan():
    """Φ < 2 gives NaN for S and the n values, while the bounds stay defined."""
    G = np.zeros((3, 180))
    G[1, 4] = 1
    G[2, [4, 9]] = 1
    res = sync_index_from_bins(G)
    assert np.isnan(res.S[:2]).all() and np.isnan(res.n_AB[:2]).all()
    assert np.isfinite(res.S[2]) and res.n_AB_max == pytest.approx(90.0)


def test_invalid_thresholds():
    """Thresholds outside (0, 1) are refused."""
    with pytest.raises(ValueError, match="tau_bc"):
        sync_index_from_bins(np.ones(10), tau_bc=1.0)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.integers(0, 50), min_size=12, max_size=40).filter(lambda g: sum(g) >= 2),
    st.integers(0, 39),
    st.booleans(),
)
def test_bounds_contain_every_histogram(counts, shift, smooth):
    """For any counts 0 ≤ S_AB, S_BC ≤ 1 (n between its bounds) and a circular shift of the bins changes nothing."""
    G = np.array(counts)
    res = sync_index_from_bins(G, smooth=smooth)
    assert res.n_AB_min - 1e-9 <= res.n_AB <= res.n_AB_max + 1e-9
    assert res.n_BC_min - 1e-9 <= res.n_BC <= res.n_BC_max + 1e-9
    assert -1e-9 <= res.S <= 1 + 1e-9
    assert sync_index_from_bins(np.roll(G, shift), smooth=smooth).S == pytest.approx(res.S, abs=1e-12)


def _phasors(phases, amplitudes=None):
    amplitudes = np.ones_like(phases) if amplitudes is None else amplitudes
    return (amplitudes * np.exp(1j * phases)).astype(np.complex64)


def test_identical_phases_give_one():
    """Patches with identical phases (any amplitudes above the threshold) give S = 1, R_w = 1, Φ = all."""
    rng = np.random.default_rng(2)
    phase = rng.uniform(-np.pi, np.pi, size=(5, 1))
    X = _phasors(np.repeat(phase, 300, axis=1), rng.uniform(0.5, 1.0, size=(5, 300)))
    res = sync_index(X, null_trials=0)
    np.testing.assert_allclose(res.S, 1.0, atol=1e-9)
    np.testing.assert_allclose(res.R_w, 1.0, atol=1e-6)
    assert res.Phi.tolist() == [300] * 5
    assert np.isnan(res.S_null).all()


def test_random_phases_match_null_level():
    """Uniformly random phases give S at the Monte-Carlo null level of the same Φ, well above 0."""
    rng = np.random.default_rng(3)
    X = _phasors(rng.uniform(-np.pi, np.pi, size=(300, 400)))
    res = sync_index(X)
    assert (res.Phi == 400).all()
    assert res.S.mean() == pytest.approx(res.S_null[0], abs=0.01)
    assert 0.2 < res.S_null[0] < 0.4
    assert res.R_w.mean() < 0.1


def test_null_level_properties():
    """The null level is NaN for Φ < 2, seeded per Φ (independent of other Φ) and falls with Φ."""
    level = sync_null_level(np.array([[0, 1], [2, 40]]), trials=50)
    assert level.shape == (2, 2) and np.isnan(level[0]).all()
    alone = sync_null_level(np.array([40]), trials=50)
    assert alone[0] == level[1, 1]
    assert sync_null_level(np.array([40]), trials=50, seed=1)[0] != alone[0]
    falling = sync_null_level(np.array([5, 50, 500]), trials=50)
    assert falling[0] > falling[1] > falling[2] > 0


def test_common_phase_shift_by_whole_bins_is_exact():
    """Adding the same whole number of bins to every phase leaves S unchanged (the histogram only rotates)."""
    rng = np.random.default_rng(4)
    centres = -np.pi + (rng.integers(0, 180, size=(20, 250)) + rng.uniform(0.2, 0.8, size=(20, 250))) * BIN
    base = sync_index(_phasors(centres), null_trials=0)
    shifted = sync_index(_phasors(centres + 37 * BIN), null_trials=0)
    np.testing.assert_allclose(shifted.S, base.S, atol=1e-12)
    np.testing.assert_allclose(shifted.R_w, base.R_w, atol=1e-5)


def test_common_phase_shift_is_approximately_invariant():
    """An arbitrary common phase shift changes S of a phase cluster only by re-binning noise (< 0.01)."""
    rng = np.random.default_rng(5)
    phases = rng.normal(0.0, 0.3, size=(30, 1000))
    base = sync_index(_phasors(phases), null_trials=0).S
    for shift in (0.37 * BIN, 1.3):
        assert np.abs(sync_index(_phasors(phases + shift), null_trials=0).S - base).max() < 0.01
    assert 0.8 < base.mean() < 0.95


def test_patch_order_is_irrelevant():
    """Permuting the patch columns leaves S, Φ and R_w unchanged."""
    rng = np.random.default_rng(6)
    X = _phasors(rng.vonmises(0.5, 2.0, size=(40, 200)), rng.exponential(1.0, size=(40, 200)))
    perm = rng.permutation(200)
    a, b = sync_index(X, null_trials=0), sync_index(X[:, perm], null_trials=0)
    np.testing.assert_array_equal(a.S, b.S)
    np.testing.assert_array_equal(a.Phi, b.Phi)
    np.testing.assert_allclose(a.R_w, b.R_w, rtol=1e-6)


def test_counting_rules_and_params():
    """The relative rule counts |X_i| ≥ η·max, the SNR rule |X_i| ≥ κ·median_f |X_i|; both are recorded."""
    amplitudes = np.array([[1.0, 0.5, 0.11, 0.09, 0.0], [1.0, 1.0, 1.0, 1.0, 1.0], [0.0, 0.0, 0.0, 0.3, 0.0]])
    X = _phasors(np.zeros_like(amplitudes), amplitudes)
    rel = sync_index(X, eta=0.1, null_trials=0)
    assert rel.Phi.tolist() == [3, 5, 1]
    assert np.isnan(rel.S[2]) and np.isfinite(rel.S[:2]).all()
    assert rel.rule == "relative" and rel.params["eta"] == 0.1 and rel.params["n_bins"] == 180
    snr = sync_index(X, rule="snr", snr=1.5, null_trials=0)  # medians per patch: 1, 0.5, 0.11, 0.3, 0
    assert snr.Phi.tolist() == [0, 4, 0]
    assert snr.params["snr"] == 1.5 and "median" in snr.params["snr_reference"]
    floor = np.full(5, 0.1)
    assert sync_index(X, rule="snr", snr=5.0, noise_floor=floor, null_trials=0).Phi.tolist() == [2, 5, 0]
    with pytest.raises(ValueError, match="rule"):
        sync_index(X, rule="energy")


def test_amplitude_weighted_order_parameter():
    """R_w is 0 for two equal groups in antiphase, the weighted imbalance otherwise, NaN for all-zero rows."""
    X = _phasors(
        np.array([[0.0, 0.0, np.pi, np.pi], [0.0, 0.0, np.pi, np.pi], [0.0] * 4]),
        np.array([[1.0, 1.0, 1.0, 1.0], [3.0, 1.0, 1.0, 1.0], [0.0] * 4]),
    )
    res = sync_index(X, null_trials=0)
    assert res.R_w[0] == pytest.approx(0.0, abs=1e-6)
    assert res.R_w[1] == pytest.approx(2.0 / 6.0, rel=1e-6)
    assert np.isnan(res.R_w[2])


def test_streamed_chunks_equal_array():
    """Feeding frequency chunks as an iterator (and small row blocks) gives the same result as one array."""
    rng = np.random.default_rng(7)
    X = _phasors(rng.vonmises(0.0, 1.0, size=(50, 120)), rng.exponential(1.0, size=(50, 120)))
    freq = np.linspace(1e3, 5e4, 50)
    whole = sync_index(X, freq=freq)
    streamed = sync_index((X[i : i + 17] for i in range(0, 50, 17)), freq=freq, rows_per_block=5)
    for key in ("S", "S_AB", "S_BC", "Phi", "S_null", "R_w"):
        np.testing.assert_array_equal(getattr(streamed, key), getattr(whole, key))
    floor = np.median(np.abs(X), axis=0)
    snr_whole = sync_index(X, rule="snr", null_trials=0)
    snr_streamed = sync_index(iter([X[:20], X[20:]]), rule="snr", noise_floor=floor, null_trials=0)
    np.testing.assert_array_equal(snr_streamed.S, snr_whole.S)
    with pytest.raises(ValueError, match="noise_floor"):
        sync_index(iter([X]), rule="snr")
    with pytest.raises(ValueError, match="freq"):
        sync_index(X, freq=freq[:-1])


def _patch_signals(n=4096, dt=1e-6, n_sync=30, n_quiet=10, seed=8):
    """30 patches in phase at an on-bin frequency plus 10 quiet noisy patches; returns (v, dt, f0)."""
    rng = np.random.default_rng(seed)
    f0 = 200 / (n * dt)
    t = np.arange(n) * dt
    v = np.empty((n, n_sync + n_quiet))
    v[:, :n_sync] = np.cos(2 * np.pi * f0 * t + 0.7)[:, None] * rng.uniform(0.5, 1.0, n_sync)
    v[:, n_sync:] = 0.05 * rng.standard_normal((n, n_quiet))
    return v[:, rng.permutation(v.shape[1])], dt, f0


def test_from_signals_matches_spectra_and_finds_synchrony():
    """sync_index_from_signals equals sync_index on complex_spectrum and finds the in-phase group at f0."""
    v, dt, f0 = _patch_signals()
    band = (0.5 * f0, 2.0 * f0)
    res = sync_index_from_signals(v, dt, freq_range=band, chunk_patches=7)
    freq, X = complex_spectrum(v.astype(np.float32), dt, freq_range=band)
    ref = sync_index(X, freq=freq)
    np.testing.assert_array_equal(res.freq, freq)
    np.testing.assert_allclose(res.S, ref.S, atol=1e-12)
    np.testing.assert_array_equal(res.Phi, ref.Phi)
    k = np.argmin(np.abs(freq - f0))
    assert res.Phi[k] == 30 and res.S[k] == pytest.approx(1.0, abs=1e-9) and res.R_w[k] > 0.95
    assert res.S_null[k] < 0.9


def test_from_signals_hdf5_and_multipass(tmp_path, monkeypatch):
    """h5py Datasets (column- or time-chunked, read in small row blocks and patch groups) and a band split
    over several passes give the single-pass in-memory result."""
    monkeypatch.setattr(sync, "_READ_BYTES", 6000)  # many row blocks per group
    v, dt, _ = _patch_signals()
    with h5py.File(tmp_path / "v.h5", "w") as f:
        by_patch = f.create_dataset("a", data=v.astype(np.float32), chunks=(v.shape[0], 4))
        by_time = f.create_dataset("b", data=v, chunks=(256, v.shape[1]))
        for rule in ("relative", "snr"):
            ref = sync_index_from_signals(v, dt, rule=rule, null_trials=0)
            assert ref.freq[0] > 0 and ref.freq.size == v.shape[0] // 2
            others = [
                sync_index_from_signals(by_patch, dt, rule=rule, chunk_patches=6, null_trials=0),
                sync_index_from_signals(by_time, dt, rule=rule, chunk_patches=7, null_trials=0),
                sync_index_from_signals(by_time, dt, rule=rule, max_bytes=300 * 8 * v.shape[1], null_trials=0),
            ]
            for other in others:
                np.testing.assert_array_equal(other.Phi, ref.Phi)
                np.testing.assert_allclose(other.S, ref.S, atol=1e-12)
                np.testing.assert_allclose(other.R_w, ref.R_w, rtol=1e-5)
