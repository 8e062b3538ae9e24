"""CUDA fast math, a run option of the on-chip strang kernel: where it is refused (with one line, before any file
exists), how the options keep it, the benchmark's axis and the statistical study's setting that measures it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from procs import one_shard_sweep

from aca_warp.bench import run_bench
from aca_warp.cli import main
from aca_warp.common.errors import SceneError
from aca_warp.hf.model import build_model
from aca_warp.hf.onchip_layout import choose_engine, fast_math_refusal
from aca_warp.hf.options import RunOptions
from aca_warp.scene import Record, preset
from aca_warp.studies import work_precision_stats as wps
from aca_warp.studies import work_precision_stats_rule as rule


def _model(device: str, precision: str = "fp32"):
    s = preset("hf1").replace(record=Record(sample_dt=1e-7))
    return build_model([s], device=device, precision=precision)


def test_options_keep_fast_math():
    assert RunOptions().fast_math is False
    on = RunOptions(fast_math=True)
    assert RunOptions.from_dict(json.loads(on.to_json())) == on
    old = json.loads(RunOptions().to_json())
    del old["fast_math"]  # a run file written before the option: the exact kernel
    assert RunOptions.from_dict(old).fast_math is False
    with pytest.raises(SceneError, match="fast_math must be true or false"):
        RunOptions(fast_math="yes")  # type: ignore[arg-type]


def test_fast_math_refusals(device):
    fp32, fp64 = _model(device), _model(device, "fp64")
    assert "on-chip strang kernel only" in fast_math_refusal(fp32, "general", "strang")
    assert "on-chip strang kernel only" in fast_math_refusal(fp32, "onchip", "adaptive")
    assert choose_engine(fp32, "auto", "strang", fast_math=False) == "onchip"
    with pytest.raises(SceneError, match="fast_math=True: it compiles the on-chip strang kernel only"):
        choose_engine(fp32, "auto", "implicit-friction", fast_math=True)
    if fp32.device.is_cpu:
        assert "CUDA devices only" in fast_math_refusal(fp32, "onchip", "strang")
        with pytest.raises(SceneError, match="CUDA devices only"):
            choose_engine(fp32, "auto", "strang", fast_math=True)
    else:
        assert choose_engine(fp32, "auto", "strang", fast_math=True) == "onchip"
        with pytest.raises(SceneError, match="single-precision arithmetic only"):
            choose_engine(fp64, "onchip", "strang", fast_math=True)


def test_hf_fast_math_on_the_cpu_is_refused_before_a_file_exists(tmp_path: Path, capsys):
    out = tmp_path / "run.h5"
    code = main(["hf", "hf1", "-o", str(out), "--fast-math", "--precision", "fp32", "--duration", "1e-6"])
    assert code == 2
    assert "--fast-math: it applies to CUDA devices only" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # no run file, no partial file, no lock
    assert main(["hf", "--resume", str(out), "--fast-math"]) == 2  # a resumed run keeps its file's options
    assert "drop --fast-math" in capsys.readouterr().err


def test_bench_math_axis():
    with pytest.raises(SceneError, match="fp32 only"):
        run_bench(precisions=("fp64",), maths=("fast",), duration=2e-6, reference=False)
    with pytest.raises(SceneError, match="CUDA devices only"):  # fp32 on-chip strang: refused by the engine choice
        run_bench(precisions=("fp32",), maths=("fast",), patches=30, duration=2e-6, reference=False, stages=False)
    out = run_bench(precisions=("fp32",), patches=30, duration=2e-6, reference=False, stages=False)
    assert [r["fast_math"] for r in out["results"]] == [False]  # exact by default


def test_study_setting_fast():
    (s,) = wps.parse_setting("strang@fp32:dt=1e-7:fast")
    assert s.fast_math and s.label == "strang@fp32:dt=1e-07:fast"
    assert wps.parse_setting(s.label) == [s]
    assert [x.fast_math for x in wps.parse_setting("strang@fp32:dt=1e-7,2e-7")] == [False, False]
    for bad, why in (
        ("strang@fp64:dt=1e-7:fast", "single-precision arithmetic only"),
        ("adaptive@fp32:fast", "on-chip strang kernel only"),
        ("strang@fp32,fp64:fast", "single-precision arithmetic only"),
    ):
        with pytest.raises(ValueError, match=why):
            wps.parse_setting(bad)


def test_a_fast_math_row_is_not_the_reference_twin():
    """The twin (the reference's setting in the other precision) is as exact as the reference: a fast-math row of
    the same step is not it."""
    ref = {"label": "strang@fp64:dt=1e-08", "role": "reference", "integrator": "strang", "precision": "fp64",
           "dt": 1e-8, "tolerance": None, "complete": True, "values": {"mu_mean": [0.5]}}  # fmt: skip
    fast = {**ref, "label": "strang@fp32:dt=1e-08:fast", "role": "grid", "precision": "fp32", "fast_math": True}
    exact = {**fast, "label": "strang@fp32:dt=1e-08", "fast_math": False}
    assert rule.twin_of({"reference": ref["label"], "settings": [ref, fast]}) is None
    assert rule.twin_of({"reference": ref["label"], "settings": [ref, fast, exact]}) is exact


def _spec_doc(**run):
    return {"sweep": {"base": "hf1", "shard_size": 2}, "run": {"duration": 1e-6, "precision": "fp32", **run},
            "parameters": {"friction.M": [0.7, 0.8]}}  # fmt: skip


def test_sweep_spec_fast_math():
    from aca_warp.sweep.spec import SweepError, load_spec

    exact = load_spec(_spec_doc())
    assert not exact.fast_math and "fast_math" not in exact.run_settings()  # earlier sweeps keep their hashes
    assert load_spec(_spec_doc(fast_math=False)).hash == exact.hash
    fast = load_spec(_spec_doc(fast_math=True))
    assert fast.fast_math and fast.run_settings()["fast_math"] is True and fast.hash != exact.hash
    assert load_spec(_spec_doc(), fast_math=True).hash == fast.hash  # --fast-math as the spec's key
    with pytest.raises(SweepError, match=r"run.fast_math \(--fast-math\): it changes single-precision"):
        load_spec(_spec_doc(fast_math=True, precision="fp64"))
    with pytest.raises(SweepError, match="true or false"):
        load_spec(_spec_doc(fast_math=1))
    from aca_warp.sweep.prepare import run_options

    assert run_options(fast).fast_math and not run_options(exact).fast_math


def test_sweep_fast_math_on_the_cpu_is_refused(tmp_path: Path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nbase = "hf1"\n[run]\nduration = 1e-6\nprecision = "fp32"\n')
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "-o", str(out), "--fast-math", "--quiet"]) == 2
    assert "CUDA devices only" in capsys.readouterr().err
    assert not out.exists()


def test_fast_math_reaches_the_cuda_kernel(device):
    """On CUDA the option compiles another kernel: fp32 results change in their last bits, not more (20 µs of an
    hf1 pad sliding, before the run's own chaos could part them)."""
    if device == "cpu":
        pytest.skip("fast math is refused on the CPU (test_fast_math_refusals)")
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.state import initial_state

    model = _model(device)
    mu = {}
    for fast in (False, True):
        res = run_hf(model, initial_state(model), RunOptions(duration=2e-5, dt=1e-8, engine="onchip", fast_math=fast))
        mu[fast] = res.collect().globals[:, 0, 0]
    assert not (mu[True] == mu[False]).all()
    assert abs(mu[True] - mu[False]).max() <= 1e-4 * abs(mu[False]).max()


def _mark_fast(path: Path, attr: str = "run_options") -> None:
    """Write ``fast_math: true`` into a file's stored options (a run file's ``run_options``, a shard's ``run``)."""
    import h5py

    with h5py.File(path, "r+") as f:
        doc = json.loads(f.attrs[attr])
        doc["fast_math"] = True
        f.attrs[attr] = json.dumps(doc)


def test_rerun_and_resume_of_a_fast_math_run_on_the_cpu_say_why(tmp_path: Path, capsys):
    run = tmp_path / "run.h5"
    argv = ["hf", "hf1", "-o", str(run), "--precision", "fp32", "--duration", "2e-7", "--sample-dt", "1e-7"]
    assert main([*argv, "--no-progress"]) == 0
    _mark_fast(run)
    capsys.readouterr()
    assert main(["rerun", str(run), "-o", str(tmp_path / "again.h5"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ran with CUDA fast math, which runs on CUDA devices only: give --device cuda:N" in err[0]
    assert not (tmp_path / "again.h5").exists()
    import h5py

    with h5py.File(run, "r+") as f:  # as a run stopped before its end leaves its file
        f.attrs["complete"] = False
    assert main(["hf", "--resume", str(run), "--no-progress"]) == 2
    assert "ran with CUDA fast math" in capsys.readouterr().err


def test_a_pad_of_a_fast_math_shard_keeps_fast_math(tmp_path: Path):
    import h5py

    from aca_warp.analysis.pads import write_pad_run
    from aca_warp.sweep import load_spec

    shard = one_shard_sweep(tmp_path, [0.7, 0.8], duration=2e-7, sample_dt=1e-7)
    _mark_fast(shard, "run")  # as a CUDA sweep with --fast-math writes it: its run settings, and the hash of them
    with h5py.File(shard, "r+") as f:
        doc, run = json.loads(f.attrs["spec"]), json.loads(f.attrs["run"])
        f.attrs["spec_hash"] = load_spec({**doc, "run": run}, base_dir=shard.parent).hash
    with h5py.File(write_pad_run(shard, 1, tmp_path / "pad1.h5"), "r") as f:
        assert json.loads(f.attrs["run_options"])["fast_math"] is True


def test_the_sweep_worker_rebuilds_fast_math_from_the_doc():
    import copy

    from aca_warp.sweep.spec import _resolve, load_spec

    spec = load_spec(_spec_doc(), fast_math=True)  # the command line's override, written into the doc
    assert _resolve(copy.deepcopy(spec.doc), spec.base_dir, check=False).fast_math


def test_labels_and_the_study_run_path():
    from aca_warp.bench import _engine_cell
    from aca_warp.hf.state import initial_state
    from aca_warp.studies.runs import run_engine
    from aca_warp.studies.work_precision_stats_report import setting_family

    assert _engine_cell({"engine": "onchip", "blocks_per_pad": 2, "fast_math": True}) == "onchip ×2, fast math"
    assert setting_family({"integrator": "strang", "precision": "fp32", "fast_math": True}) == "strang@fp32 fast math"
    with pytest.raises(SceneError, match="CUDA devices only"):  # the study's runs pass the setting's fast math on
        model = _model("cpu")
        run_engine(model, initial_state(model), engine="auto", duration=1e-7, integrator="strang", dt=1e-8,
                   record=Record(sample_dt=1e-7), fast_math=True)  # fmt: skip
    with pytest.raises(SystemExit):
        wps.main(["--reference", "strang@fp32:dt=1e-8:fast", "--out", "unused"])


def test_bench_cases_take_fast_math_where_it_fits():
    from aca_warp.bench import _cases

    got = list(_cases((1,), ("fp64", "fp32"), ("strang", "adaptive"), ("auto", "general"), ("exact", "fast")))
    assert [c for c in got if c[4]] == [(1, "fp32", "strang", "auto", True)]
    assert len([c for c in got if not c[4]]) == 8  # every exact case
