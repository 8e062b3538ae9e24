"""``aca-warp bench`` on a tiny CPU case: JSON keys, stage times, exit codes; the script wrapper; the byte model."""

from __future__ import annotations

import json
import os
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
    """``--dt default``: the scene's own default step (hf1's 1e-6/3 s for its physics, 5e-8 s once the patch count
    differs from the preset's, the sample interval where that is shorter down to 5e-8 s), recorded as such."""
    cases = ((None, 1e-6, 1e-6 / 3, 6), (10, 1e-6, 5e-8, 40), (None, 5e-8, 5e-8, 40))
    for i, (patches, sample, dt, steps) in enumerate(cases):
        out, md = tmp_path / f"d{i}.json", tmp_path / f"d{i}.md"
        args = ["bench", "--dt", "default", "--duration", "2e-6", "--precision", "fp32", "--no-reference"]
        args += ["--no-stages", "--json", str(out), "--markdown", str(md), "--sample-dt", str(sample)]
        assert main(args + ([] if patches is None else ["--patches", str(patches)])) == 0
        doc = json.loads(out.read_text())
        assert doc["dt_s"] == dt and doc["dt_is_default"] and doc["results"][0]["steps"] == steps
        assert f"dt = {dt:g} s (strang's default for the scene)" in md.read_text()


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
    assert (on["blocks_per_pad"], on["block_dim"]) == (1, 32) and rows[0]["block_dim"] is None  # the launch layout
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


QUICK = ["bench", "--patches", "10", "--duration", "2e-6", "--precision", "fp32", "--no-reference", "--no-stages"]


def _error(capsys: pytest.CaptureFixture) -> tuple[str, list[str]]:
    """stdout and the error lines of stderr of the command just run."""
    captured = capsys.readouterr()
    return captured.out, [line for line in captured.err.splitlines() if line.strip()]


def test_bench_keeps_an_existing_output_unless_overwrite(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """An existing --json or --markdown file is refused before anything is measured (a run file stays a run file);
    --overwrite replaces it."""
    precious = tmp_path / "precious.h5"
    precious.write_bytes(b"\x89HDF\r\n\x1a\n run file")
    for flag in ("--json", "--markdown"):
        assert main([*QUICK, flag, str(precious)]) == 2
        out, err = _error(capsys)
        assert err == [f"aca-warp: error: output file {precious} exists; pass --overwrite to replace it"]
        assert "pads=" not in out and precious.read_bytes() == b"\x89HDF\r\n\x1a\n run file"
    assert main([*QUICK, "--json", str(precious), "--overwrite"]) == 0
    assert json.loads(precious.read_text())["results"][0]["patches"] == 10
    assert sorted(p.name for p in tmp_path.iterdir()) == ["precious.h5"]  # no temporary file left


def test_bench_refuses_a_folder_or_an_unwritable_one_before_measuring(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A folder named as the output: exit 2; a folder that takes no new file (a read-only file system): exit 4;
    both one line, before the first case."""
    import errno

    from aca_warp.common import files

    figs = tmp_path / "figs"
    figs.mkdir()
    for name, said in ((str(figs), f"{figs} is a folder"), (f"{figs}/", f"'{figs}/' names a folder")):
        assert main([*QUICK, "--json", name]) == 2
        out, err = _error(capsys)
        assert err == [f"aca-warp: error: --json {said}; give a file name such as {figs}/bench.json"]
        assert "pads=" not in out

    def read_only(folder: str | Path) -> None:
        raise files.unwritable(folder, OSError(errno.EROFS, "Read-only file system"))

    monkeypatch.setattr(files, "probe_folder", read_only)
    assert main([*QUICK, "--json", str(figs / "b.json")]) == 4
    out, err = _error(capsys)
    assert len(err) == 1 and "read-only file system" in err[0] and "pads=" not in out
    assert list(figs.iterdir()) == []


def test_bench_writes_its_files_whole(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A write that fails at the end: one line, exit 4, the measured lines printed, no half file and no temporary
    file left. A name taken by a folder while the cases ran: the other file written, as the line says; the device
    full: nothing written, the old file as it was."""
    import aca_warp.bench as bench
    from aca_warp.common import links

    out, md = tmp_path / "b.json", tmp_path / "b.md"
    real_run = bench.run_bench

    def run_then_take_the_name(**kw: object) -> dict:
        result = real_run(**kw)
        md.mkdir()
        (md / "x").write_text("")
        return result

    monkeypatch.setattr(bench, "run_bench", run_then_take_the_name)
    assert main([*QUICK, "--json", str(out), "--markdown", str(md)]) == 4
    printed, err = _error(capsys)
    assert len(err) == 1 and f"cannot write {md} (" in err[0] and f"{out} written, the rest not" in err[0], err
    assert "pads=" in printed and "wrote" not in printed
    assert json.loads(out.read_text())["results"] and sorted(p.name for p in tmp_path.iterdir()) == ["b.json", "b.md"]
    monkeypatch.undo()

    out.write_text("old")
    real = links.create_new

    def full(path: Path, what: str, mode: int = 0o644) -> int:  # the temporary file lands on a full device
        os.close(real(path, what, mode))
        return os.open("/dev/full", os.O_WRONLY)

    monkeypatch.setattr(links, "create_new", full)
    assert main([*QUICK, "--json", str(out), "--markdown", str(tmp_path / "c.md"), "--overwrite"]) == 4
    printed, err = _error(capsys)
    assert len(err) == 1 and "no space left on device" in err[0] and "nothing was written" in err[0], err
    assert "pads=" in printed and "wrote" not in printed
    assert out.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["b.json", "b.md"]


def test_bench_refuses_one_file_twice_and_an_empty_name(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """--json and --markdown naming one file (however spelled), or an empty name: exit 2, one line, nothing run."""
    b1 = tmp_path / "b1.json"
    for md in (str(b1), f"{tmp_path}/./b1.json"):
        assert main([*QUICK, "--json", str(b1), "--markdown", md]) == 2
        out, err = _error(capsys)
        assert len(err) == 1 and "--json and --markdown name the same file" in err[0] and "pads=" not in out
    for flag, example in (("--json", "bench.json"), ("--markdown", "bench.md")):
        assert main([*QUICK, flag, ""]) == 2
        out, err = _error(capsys)
        assert err == [f"aca-warp: error: {flag} '' names no file; give a file name such as {example}"]
    assert list(tmp_path.iterdir()) == []


def test_bench_checks_the_step_as_hf_does(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """A step longer than the sample interval, or beyond an HF step's range, is refused as by ``aca-warp hf``
    (it ran at the sample interval while the files said otherwise); a step that whole steps do not fit into a
    sample interval is reported as the step taken, with the one asked for."""
    out = tmp_path / "d.json"
    assert main([*QUICK, "--dt", "2e-6", "--duration", "1e-5", "--json", str(out)]) == 2
    printed, err = _error(capsys)
    assert len(err) == 1 and "= 1e-06 s is shorter than the step 2e-06 s" in err[0] and "pads=" not in printed
    assert main([*QUICK, "--dt", "1e-3", "--json", str(out)]) == 2
    _, err = _error(capsys)
    assert len(err) == 1 and "dt = 0.001 s — beyond 1e-05 s" in err[0] and "did you mean µs?" in err[0]
    assert main([*QUICK, "--dt", "1e-3", "--allow-implausible", "--json", str(out)]) == 2  # past that check only
    _, err = _error(capsys)
    assert len(err) == 1 and "is shorter than the step 0.001 s" in err[0]
    assert not out.exists()
    md = tmp_path / "d.md"
    assert main([*QUICK, "--dt", "3e-8", "--json", str(out), "--markdown", str(md)]) == 0
    doc = json.loads(out.read_text())
    taken = 1e-6 / 34  # 34 steps per sample interval
    assert doc["dt_s"] == pytest.approx(taken, rel=1e-12) and doc["dt_asked_s"] == 3e-8
    assert doc["results"][0]["dt"] == pytest.approx(taken, rel=1e-12) and doc["results"][0]["steps"] == 68
    assert f"dt = {taken:g} s (3e-08 s asked, shortened so that whole steps fill" in md.read_text()


def test_bench_refuses_options_that_leave_no_case(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The on-chip engine alone with an integrator it does not implement: exit 2 and why, not an empty result."""
    out = tmp_path / "se.json"
    args = [*QUICK, "--engine", "onchip", "--integrator", "symplectic-euler", "--json", str(out)]
    assert main(args) == 2
    printed, err = _error(capsys)
    assert err == [
        "aca-warp: error: --engine onchip: the on-chip engine implements the strang and adaptive integrators only "
        "(got symplectic-euler): no case to run; add --engine general or one of those integrators"
    ]
    assert "pads=" not in printed and not out.exists()


def test_bench_header_names_a_tolerance_only_for_a_case_that_has_one(tmp_path: Path) -> None:
    """The Markdown header names the adaptive tolerance only when an adaptive case ran."""
    md = tmp_path / "s.md"
    assert main([*QUICK, "--markdown", str(md)]) == 0
    assert "tolerance" not in md.read_text()
    md2 = tmp_path / "a.md"
    assert main([*QUICK, "--integrator", "strang", "adaptive", "--engine", "general", "--markdown", str(md2)]) == 0
    head = md2.read_text().splitlines()[0]
    assert "(adaptive: tolerance 1e-05)" in head and "split tolerance" not in head


def test_every_integrator_is_benched_with_its_stages(tmp_path: Path) -> None:
    """With the stages timed (the default), every integrator runs; the step-controlled ones have no bare fixed step
    (no stepping time), the fixed-step ones do (``scripts/bench_hf.py`` benches every integrator)."""
    from aca_warp.hf.options import INTEGRATORS, STEP_CONTROLLED

    out = tmp_path / "all.json"
    args = ["bench", "--patches", "10", "--duration", "2e-6", "--precision", "fp64", "--no-reference"]
    assert main([*args, "--engine", "general", "--integrator", *INTEGRATORS, "--json", str(out)]) == 0
    rows = json.loads(out.read_text())["results"]
    assert [r["integrator"] for r in rows] == list(INTEGRATORS)
    for r in rows:
        assert (r["stepping_s"] is None) == (r["integrator"] in STEP_CONTROLLED), r
    from aca_warp.bench import markdown

    table = markdown(json.loads(out.read_text()))
    assert "| controlled | general |" in table and "– (no fixed step)" in table and "(on chip)" not in table


def test_a_link_planted_at_a_benchs_temporary_file_is_refused_as_a_link(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A link another user plants where the JSON's temporary file goes, while the cases run: the link refusal (exit
    2), not a storage failure, and nothing written through it."""
    import aca_warp.bench as bench

    out, victim = tmp_path / "b.json", tmp_path / "victim"
    victim.write_text("keep")
    real_run = bench.run_bench

    def run_then_plant(**kw: object) -> dict:
        result = real_run(**kw)
        (tmp_path / ".b.partial.json").symlink_to(victim)
        return result

    monkeypatch.setattr(bench, "run_bench", run_then_plant)
    assert main([*QUICK, "--json", str(out)]) == 2
    printed, err = _error(capsys)
    assert len(err) == 1 and "cannot write" not in err[0], err
    assert victim.read_text() == "keep" and not out.exists()
