"""scripts/compare_checkouts.py: the sizes of the differences it reports and the sweep specs it writes."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from tests.scriptload import load_script

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

cc = load_script("compare_checkouts")
REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    ("a", "b", "expected"),
    [
        ([1.0, -4.0, 2.0], [1.0, -4.0, 2.0], 0.0),
        ([1.0, -4.0, 2.0], [1.0, -4.0, 2.5], 0.125),  # 0.5 / max |a| = 4
        ([0.0, 0.0], [0.0, 1e-3], float("inf")),
        ([1.0, np.nan], [1.5, np.nan], 0.5),  # NaNs in the same places left out
        ([1.0, 2.0], [1.0, np.nan], float("inf")),  # a NaN opposite a number
    ],
)
def test_largest_relative(a, b, expected):
    """max |b − a| / max |a|, against the first array's largest value, not each element's own."""
    assert cc.largest_relative(np.array(a), np.array(b)) == expected


def test_largest_relative_not_comparable():
    """Other shapes and integer data have no relative difference."""
    assert cc.largest_relative(np.zeros(3), np.zeros(4)) is None
    assert cc.largest_relative(np.arange(3), np.arange(3) + 1) is None


def test_compare_reports_sizes(tmp_path):
    """A run file pair: the differing float dataset listed with its size, the equal one not listed."""
    paths = [tmp_path / "a.h5", tmp_path / "b.h5"]
    for path, last in zip(paths, (2.0, 2.0 + 2e-16 * 2.0), strict=True):
        with h5py.File(path, "w") as f:
            f["global/mu"] = np.array([1.0, last])
            f["global/same"] = np.arange(4.0)
    r = cc.compare(*paths)
    assert r["different"] == ["global/mu"]
    assert r["largest_relative"]["global/mu"] == pytest.approx(2.0 * np.finfo(float).eps / 2.0, rel=1e-6)
    assert "global/mu (≤ 2.2e-16 relative)" in cc.file_line(r)
    assert not cc.same_results(r)


@pytest.mark.parametrize(("job", "precision"), [("sweep_pairs", "fp32"), ("sweep_pairs_fp64", "fp64")])
def test_pair_specs(job, precision):
    """The 64-pad sweeps are valid TOML with their step and precision, one shard of 64 patch seeds, and each is a
    job."""
    spec = tomllib.loads(cc.SPECS[job])
    assert spec["run"]["precision"] == precision and spec["run"]["dt"] == 5e-8
    assert spec["sweep"]["shard_size"] == 64
    assert spec["parameters"]["patches.seed"] == {"range": [1, 65]}
    assert cc.EXTRA_JOBS[job][1] == f"{{out}}/{job}.toml"


def test_every_strang_job_names_its_step():
    """Every job of the default integrator names its step, so that checkouts on either side of a change of strang's
    default step run the same job (the sweep specs name it in their [run] table)."""
    for name, job in {**cc.JOBS, **cc.EXTRA_JOBS}.items():
        if job[0] == "hf" and "--integrator" not in job:
            assert "--dt" in job, name
        elif job[0] == "sweep" and not job[1].startswith("{out}/"):  # a packaged spec (SPECS are checked below)
            assert "dt" in tomllib.loads((REPO / job[1]).read_text())["run"], name
    for text in cc.SPECS.values():
        assert tomllib.loads(text)["run"]["dt"] == 5e-8


def test_va_pairs_spec():
    """The growing sweep: 32 varying_area pads of patch seeds 1–32 in one shard, fp32, its step and growth spacing
    named (so that both checkouts run it, whatever their defaults), and it is a job."""
    spec = tomllib.loads(cc.SPECS["sweep_va_pairs"])
    assert spec["sweep"] == {"base": "varying_area", "shard_size": 32}
    assert spec["run"] == {"duration": 1e-4, "dt": 5e-8, "precision": "fp32", "growth_dt": 5e-6}
    assert spec["parameters"]["patches.seed"] == {"range": [1, 33]}
    assert cc.EXTRA_JOBS["sweep_va_pairs"][1] == "{out}/sweep_va_pairs.toml"


def test_lf_state_job_reads_the_first_lf_file():
    """hf_lf_state runs on the LF file that the job lf_seed7 wrote from the first checkout, so both checkouts' HF runs
    start from the same state."""
    assert cc.EXTRA_JOBS["lf_seed7"][:4] == ["lf", "multiscale", "--seed", "7"]
    job = cc.EXTRA_JOBS["hf_lf_state"]
    assert job[:4] == ["hf", "{out}/lf_seed7_0.h5", "--snapshot", "app2_start"]


def test_cuda_code_of_a_checkout_against_itself(tmp_path, capsys):
    """compare_cuda_code (Warp's NVRTC, no GPU): one checkout against itself compiles to the same machine code (one
    group of eight kernels, its machine code and its PTX); two kernel sets that differ name the kernel and its
    sizes."""
    import warp as wp

    cc = load_script("compare_cuda_code")
    if 90 not in wp.get_cuda_supported_archs():
        pytest.skip("this Warp build compiles no CUDA code for sm_90")
    out = tmp_path / "code.json"
    group = "general, mean crossing"  # the quickest to compile: four small kernels in two precisions
    for mode in ([], ["--ptx"]):  # the machine code, then the PTX
        assert cc.main([str(REPO), str(REPO), "--groups", group, "--out", str(out), *mode]) == 0
        assert f"{group}: 8 kernel(s), identical" in capsys.readouterr().out
        assert json.loads(out.read_text())["ptx"] == bool(mode)
    assert cc.compare({"g": [["k", "aa", 4], ["m", "bb", 8]]}, {"g": [["k", "aa", 4], ["m", "cc", 12]]}) == {
        "g": {"kernels": 2, "identical": False, "differ": {"m": ([8], [12])}}
    }


def test_batch_checkouts_report(tmp_path, capsys):
    """compare_batch_checkouts: one checkout against itself is identical in every array, and a difference is
    counted and sized against the array's largest value."""
    cb = load_script("compare_batch_checkouts")
    out = tmp_path / "cmp.txt"
    argv = [str(REPO), str(REPO), "--device", "cpu", "--pads", "1", "--duration", "4e-6", "--precisions", "fp64"]
    assert cb.main([*argv, "--out", str(out)]) == 0
    lines = out.read_text().splitlines()
    layout = "1 block(s) per pad of 512 threads"  # the launch's block size (on the CPU a block runs as one thread)
    assert lines[1] == f"fp64 layout: {layout} against {layout}"
    assert [line.split()[1:] for line in lines[2:]] == [[k, "identical"] for k in ("globals", "velocity", "u", "v")]
    assert cb.differences(np.array([1.0, -4.0]), np.array([1.0, -3.0])) == "differ: 1 of 2, ≤ 0.25 relative"
