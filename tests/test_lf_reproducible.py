"""scripts/lf_reproducible.py: repeated LF runs of a seed compared bit for bit (here on the CPU, 0.3 s of the
multiscale schedule)."""

from __future__ import annotations

import json

import pytest
from scriptload import load_script


def test_repeated_runs_compared_bit_for_bit(tmp_path, capsys, monkeypatch):
    repro = load_script("lf_reproducible")
    args = ["--device", "cpu", "--seeds", "3", "--runs", "2", "--duration", "0.3", "--out", str(tmp_path)]
    assert repro.main(args) == 0
    out = capsys.readouterr().out
    assert "seed 3: 2 runs" in out and "datasets each, bit-identical" in out and "all bit-identical" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seed3_run1.h5", "seed3_run2.h5"]

    # runs that differ are found: here the second run of the seed gets other initial patches
    from aca_warp.studies.validation import multiscale

    calls = []
    real = multiscale.lf_scene

    def other_each_call(seed, schedule, durations):
        calls.append(seed)
        return real(seed + len(calls) - 1, schedule, durations)

    monkeypatch.setattr(multiscale, "lf_scene", other_each_call)
    assert repro.main(args) == 1
    out = capsys.readouterr().out
    assert "seed 3: 2 runs" in out and "DIFFERENT" in out and "runs DIFFER" in out


def test_first_run_checked_against_the_digests_a_results_file_records(tmp_path, capsys):
    """--digests: a run with the digest a validation results file records for its LF run file passes, another
    digest fails."""
    from aca_warp.studies.validation.multiscale import lf_file_digest

    repro = load_script("lf_reproducible")
    runs = tmp_path / "runs"
    args = ["--seeds", "2", "--runs", "2", "--duration", "0.2", "--out", str(runs)]
    assert repro.main(args) == 0
    digest = lf_file_digest(runs / "seed2_run1.h5")
    results = tmp_path / "results.json"

    def check(recorded: dict) -> int:
        results.write_text(json.dumps({"results": recorded}))
        capsys.readouterr()
        return repro.main([*args, "--digests", str(results)])

    assert check({"ms_fast": {"lf_runs": {"lf_full_preset_seed2.h5": digest}}, "hf1": {}}) == 0
    assert f"digest {digest} == recorded" in capsys.readouterr().out
    assert check({"ms_fast": {"lf_runs": {"lf_full_preset_seed2.h5": "0" * 16}}}) == 1
    assert "runs DIFFER or do not have the recorded digests" in capsys.readouterr().out


TWO = {"a": {"lf_runs": {"lf_full_preset_seed2.h5": "0"}}, "b": {"lf_runs": {"lf_full_preset_seed2.h5": "1"}}}
OTHER_SEED = {"ms_fast": {"lf_runs": {"lf_full_preset_seed9.h5": "0"}}}


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "No such file"),
        ("{not json", "Expecting property name"),
        ([1, 2], "'list' object has no attribute"),
        ({"results": {"ms_fast": {"lf_runs": ["lf_full_preset_seed2.h5"]}}}, "'list' object has no attribute"),
        ({"results": TWO}, "recorded with two digests"),
        ({"results": {"hf1": {}}}, "records no LF runs"),
        ({"results": OTHER_SEED}, "records no LF run lf_full_preset_seed2.h5"),
    ],
)
def test_bad_digests_file(tmp_path, capsys, content, message):
    """A --digests file that cannot be read, is not a results file, records one LF run with two digests, records
    none, or does not record a seed asked for: exit code 2 with the reason, before any run is made."""
    repro = load_script("lf_reproducible")
    results = tmp_path / "results.json"
    if content is not None:
        results.write_text(content if isinstance(content, str) else json.dumps(content))
    out = tmp_path / "runs"
    with pytest.raises(SystemExit) as e:
        repro.main(["--seeds", "2", "--duration", "0.2", "--out", str(out), "--digests", str(results)])
    assert e.value.code == 2 and message in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("bad", [["--runs", "1"], ["--duration", "-1"], ["--seeds", "x"]])
def test_bad_arguments(bad, capsys):
    repro = load_script("lf_reproducible")
    with pytest.raises(SystemExit) as e:
        repro.main(bad)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("usage:") or "error:" in err[-1]


def test_digests_read_from_a_results_file_or_its_gzip():
    """The committed eight-seed runs of two code versions and the 32-seed file (gzip) record the same digest for
    every LF run they share: the LF runs of seeds 1–8 regenerate bit for bit across those runs."""
    from pathlib import Path

    repro = load_script("lf_reproducible")
    docs = Path(__file__).resolve().parents[1] / "docs" / "validation"
    eight = repro.recorded_digests(docs / "results.json")
    assert len(eight) == 16
    for other in ("rerun_twice/results.json", "rerun_twice/results_b.json.gz", "seeds32/results.json.gz"):
        got = repro.recorded_digests(docs / other)
        assert {k: got.get(k) for k in eight} == eight, other
