"""``aca-warp bench`` on a tiny CPU case: JSON keys, stage times, exit codes; the script wrapper; the byte model."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scriptload import load_script

from aca_warp.bench import bytes_per_step
from aca_warp.cli import main

KEYS = (
    "device",
    "warp_version",
    "precision",
    "patches",
    "pads",
    "steps_per_s",
    "patch_steps_per_s",
    "ns_per_patch_step",
    "compile_time_s",
    "module_load_s",
    "contact_s",
    "neighbours_s",
    "model_build_s",
    "capture_s",
    "stepping_s",
    "recording_s",
    "bytes_per_step",
    "bandwidth_Bps",
    "peak_bandwidth_Bps",
    "peak_bandwidth_source",
    "mu_rel_error_max",
)


def test_bench_cli_json(tmp_path: Path) -> None:
    out = tmp_path / "b.json"
    md = tmp_path / "b.md"
    args = ["bench", "--patches", "20", "--duration", "3e-6", "--precision", "fp32", "--pads", "1", "2"]
    args += ["--engine", "general"]  # the per-stage timings are the general engine's
    assert main([*args, "--json", str(out), "--markdown", str(md)]) == 0
    doc = json.loads(out.read_text())
    rows = doc["results"]
    assert [(r["pads"], r["patches"]) for r in rows] == [(1, 20), (2, 40)]
    for r in rows:
        assert all(k in r for k in KEYS), [k for k in KEYS if k not in r]
        assert r["device"] == "cpu" and r["precision"] == "fp32" and r["steps"] == 300
        assert r["patch_steps_per_s"] == pytest.approx(r["patches"] * r["steps_per_s"])
        assert r["ns_per_patch_step"] == pytest.approx(1e9 / r["patch_steps_per_s"])
        assert 0 < r["stepping_s"] and r["recording_s"] >= 0 and r["peak_bandwidth_Bps"] > 0
        assert r["bytes_per_step"] == bytes_per_step("strang", r["patches"], r["links"], "fp32")
        assert 0 <= r["mu_rel_error_max"] < 1e-5  # fp32 strang at dt against fp64 at dt/4
    assert "| CPU | fp32 | strang | general | 2 | 40 |" in md.read_text()


def test_bench_sample_interval_longer_than_the_warm_up(tmp_path: Path) -> None:
    """A sample interval past the 2 µs warm-up: the warm-up spans one interval instead of refusing the run."""
    out = tmp_path / "b.json"
    args = ["bench", "--patches", "10", "--duration", "2e-5", "--sample-dt", "1e-5", "--precision", "fp32"]
    assert main([*args, "--no-reference", "--no-stages", "--json", str(out)]) == 0
    (row,) = json.loads(out.read_text())["results"]
    assert row["steps"] == 2000 and row["complete"]


def test_bench_takes_strangs_default_step_when_asked(tmp_path: Path) -> None:
    """``--dt default``: the scene's own default step (1e-7 s for a preset's physics, 5e-8 s once the patch count
    differs from the preset's, the sample interval where that is shorter down to 5e-8 s), recorded as such."""
    for patches, sample, dt, steps in ((None, 1e-6, 1e-7, 20), (10, 1e-6, 5e-8, 40), (None, 5e-8, 5e-8, 40)):
        out = tmp_path / f"d{patches}.json"
        args = ["bench", "--dt", "default", "--duration", "2e-6", "--precision", "fp32", "--no-reference"]
        args += ["--no-stages", "--json", str(out), "--markdown", str(tmp_path / "d.md"), "--sample-dt", str(sample)]
        assert main(args + ([] if patches is None else ["--patches", str(patches)])) == 0
        doc = json.loads(out.read_text())
        assert doc["dt_s"] == dt and doc["dt_is_default"] and doc["results"][0]["steps"] == steps
        assert f"dt = {dt:g} s (strang's default for the scene)" in (tmp_path / "d.md").read_text()


def test_bench_exit_codes(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["bench", "--duration", "1e-7", "--patches", "5", "--json", str(tmp_path / "x.json")]) == 2
    assert "(--sample-dt) exceeds the duration" in capsys.readouterr().err
    assert main(["bench", "--patches", "5", "--json", str(tmp_path / "no" / "x.json")]) == 2
    assert main(["bench", "--device", "cuda:7", "--patches", "5"]) == 2
    with pytest.raises(SystemExit):
        main(["bench", "--integrator", "rk4"])


def test_byte_model_and_script(tmp_path: Path) -> None:
    # strang fp64: n (8 + 12*8) + E (4 + 8)
    assert bytes_per_step("strang", 10, 30, "fp64") == 10 * 104 + 30 * 12
    assert bytes_per_step("symplectic-euler", 10, 30, "fp32") == 10 * 52 + 30 * 8
    out = tmp_path / "s.json"  # scripts/bench_hf.py, loaded as the script and run in this process
    argv = ["--patches", "8", "--duration", "2e-6", "--precisions", "fp64", "--integrators", "symplectic-euler"]
    assert load_script("bench_hf").main([*argv, "--no-reference", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["results"][0]["integrator"] == "symplectic-euler"


def test_bench_engines(tmp_path: Path) -> None:
    """``--engine general onchip``: one row per engine (on-chip: no bandwidth, strang only), same μ error."""
    out = tmp_path / "e.json"
    args = ["bench", "--patches", "20", "--duration", "3e-6", "--precision", "fp64", "--engine", "general", "onchip"]
    assert main([*args, "--integrator", "strang", "symplectic-euler", "--json", str(out)]) == 0
    rows = json.loads(out.read_text())["results"]
    assert [(r["integrator"], r["engine"]) for r in rows] == [
        ("strang", "general"),
        ("strang", "onchip"),
        ("symplectic-euler", "general"),
    ]
    on = rows[1]
    assert on["bandwidth_Bps"] is None and on["stepping_s"] is None and on["steps"] == 300
    assert on["mu_rel_error_max"] == pytest.approx(rows[0]["mu_rel_error_max"], rel=1e-9)


def test_ncu_summary_ranks_kernels_per_step(tmp_path: Path) -> None:
    from scriptload import load_script

    ncu = load_script("ncu_summary")
    head = '"Process ID","Process Name","Host Name","Kernel Name","Block Size","Grid Size","Device","CC",'
    head += '"Invocations","Section Name","Metric Name","Metric Unit","Minimum","Maximum","Average"'
    row = '"1","py","h","{k}","(256, 1, 1)","(4, 1, 1)","0","9.0","{n}","s","gpu__time_duration.sum","ns","1","2","{a}"'
    text = "\n".join(
        ["==PROF== Connected", "steps 10", head,
         row.format(k="small_0123abcd_cuda_kernel_forward", n=10, a="1,000.00"),
         row.format(k="void scan::Kernel<int, 3>(T2)", n=40, a="500.00")]
    )  # fmt: skip
    rows = ncu.summarise(text, steps=10)
    assert [r[0] for r in rows] == ["scan::Kernel", "small"]
    assert rows[0][3] == pytest.approx(2.0) and rows[1][3] == pytest.approx(1.0)  # µs per step
    f = tmp_path / "x.csv"
    f.write_text("no table here")
    assert ncu.main([str(f), "--steps", "1"]) == 2


def test_ncu_onchip_normalises_one_launch(tmp_path: Path) -> None:
    """scripts/ncu_onchip.py: the metrics of one launch per pad-step and patch-step; files with several launches or
    without the needed metrics are refused."""
    from scriptload import load_script

    ncu = load_script("ncu_onchip")
    head = '"ID","Kernel Name","Section Name","Metric Name","Metric Unit","Metric Value"'
    metrics = {
        "gpu__time_duration.sum": ("ns", "2,000,000"),
        "smsp__inst_executed.sum": ("inst", "4,000,000"),
        "smsp__thread_inst_executed.sum": ("inst", "96,000,000"),
        "smsp__issue_active.avg.pct_of_peak_sustained_active": ("%", "50"),
        "l1tex__data_pipe_lsu_wavefronts_mem_shared_op_ld.sum": ("", "800"),
        "l1tex__data_bank_conflicts_pipe_lsu_mem_shared_op_ld.sum": ("", "200"),
    }
    rows = [f'"0","onchip_strang","s","{k}","{u}","{v}"' for k, (u, v) in metrics.items()]
    f = tmp_path / "one.csv"
    f.write_text("\n".join(["==PROF== Connected", head, *rows]))
    row = ncu.summary_row(ncu.read_metrics(f), steps=100, patches=10, pads=2, sms=1, clock=1e9)
    assert row["us_per_step"] == pytest.approx(20.0)
    assert row["warp_inst_per_pad_step"] == pytest.approx(2.0e4)  # 4e6 / (100 steps · 2 pads)
    assert row["warp_inst_per_patch_step"] == pytest.approx(2.0e3)
    assert row["thread_inst_per_patch_step"] == pytest.approx(4.8e4)
    assert row["bank_conflict_share"] == pytest.approx(0.25)
    assert row["ceiling_patch_steps_per_s"] == pytest.approx(4e9 / 2.0e3)  # 1 SM · 4 schedulers · 1 GHz
    assert ncu.main(["--steps", "100", "--patches", "10", f"{f}=case:2"]) == 0
    two = tmp_path / "two.csv"
    two.write_text("\n".join([head, *rows, rows[0].replace('"0"', '"1"', 1)]))
    short = tmp_path / "short.csv"
    short.write_text("\n".join([head, *rows[:2]]))
    for bad in (two, short, tmp_path / "missing.csv"):
        assert ncu.main(["--steps", "1", "--patches", "1", str(bad)]) == 2


def test_bench_row_of_a_step_controlled_split_integrator_has_no_traffic_model():
    """controlled and auto mix kinds of trial: no modelled traffic (None), where a KeyError stopped the bench."""
    from aca_warp.bench import bytes_per_step

    assert bytes_per_step("strang", 10, 20, "fp32") == 10 * (8 + 48) + 20 * 8
    assert bytes_per_step("controlled", 10, 20, "fp32") is None and bytes_per_step("auto", 10, 20, "fp64") is None


def test_bench_crossing_option(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """``--crossing mean`` runs strang with the crossing steps averaged, says so in the row and the table, and is
    refused for another integrator."""
    out, md = tmp_path / "m.json", tmp_path / "m.md"
    args = ["bench", "--patches", "10", "--duration", "2e-6", "--precision", "fp64", "--no-reference", "--no-stages"]
    assert main([*args, "--crossing", "mean", "--json", str(out), "--markdown", str(md)]) == 0
    (row,) = json.loads(out.read_text())["results"]
    assert row["crossing"] == "mean" and row["complete"] and "crossings averaged" in md.read_text()
    capsys.readouterr()
    both = [*args, "--integrator", "strang", "adaptive", "--crossing", "mean", "--json", str(tmp_path / "x.json")]
    assert main(both) == 2  # refused before the strang case runs: no line of a timed case, no file
    captured = capsys.readouterr()
    assert "treatment of strang's steps" in captured.err and "pads=" not in captured.out
    assert not (tmp_path / "x.json").exists()
