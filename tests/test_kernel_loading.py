"""Every kernel a run launches is loaded in its set-up, before the clock of its stepping starts, at the block size of
its launches (a module compiles once per block size): a variant first loaded at its first launch would put its compile
(seconds on an empty kernel cache) into ``RunResult.wall_time``, the stepping time that the studies' work-precision
and the benchmarks compare, and leave it out of ``compile_time``. A graph capture loads nothing itself.

``scripts/kernel_loads.py`` runs every engine and integrator (and growing patches, and the on-chip kernels at their
real block size through Warp's cooperative CPU blocks) on a one-pad sector of this checkout, every Warp module unloaded
before each case, and lists the module variants loaded while the run stepped."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scriptload import load_script

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def loads():
    return load_script("kernel_loads")


def test_a_run_loads_every_kernel_it_launches_before_its_stepping(loads, tmp_path):
    from compare_checkouts import package_view

    rows = loads.run_cases(loads.CASES, package_view(REPO, tmp_path / "view"))
    assert [tuple(r["case"]) for r in rows] == loads.CASES
    for r in rows:
        assert r["complete"], r
        assert r["setup"], r  # the spy sees loads: every run loads its kernels again after the unloading
        assert r["stepping"] == [] and r["capture"] == [], f"{r['case']}: {r['stepping']}, in a capture {r['capture']}"
    setup = {tuple(r["case"]): {(name, dim) for name, dim in r["setup"]} for r in rows}
    names = {case: {name for name, _ in loaded} for case, loaded in setup.items()}
    # the treatment's closing kernel, not its stepping ones, on chip; the split step's module only where it runs
    assert any("strang_close" in name for name in names["strang", "onchip", "mean", "plain"])
    assert not any("strang_advance" in name for name in names["strang", "onchip", "mean", "plain"])
    assert any("strang_advance" in name for name in names["strang", "general", "mean", "plain"])
    assert "aca_warp.kernels.hf_controlled" in names["auto", "general", "point", "plain"]
    assert "aca_warp.kernels.hf_controlled" not in names["adaptive", "general", "point", "plain"]
    # with real CPU blocks every kernel is loaded at the block size it is launched with: the on-chip kernels not at
    # one thread, the explicit pair's evaluations in lanes (only where the pair runs)
    for integrator in ("strang", "adaptive"):
        onchip = setup[integrator, "onchip", "point", "cpu-blocks"]
        assert any(name.startswith("onchip_") and dim > 1 for name, dim in onchip), onchip
    lanes = {dim for name, dim in setup["adaptive", "general", "point", "cpu-blocks"] if name.endswith("hf_adaptive")}
    assert len(lanes) == 3, lanes  # plain launches, the control's blocks and the evaluations' lanes
    controlled = setup["controlled", "general", "point", "cpu-blocks"]
    assert {dim for name, dim in controlled if name.endswith("hf_adaptive")} == {1}, controlled


def test_a_capture_loads_no_module_itself(monkeypatch):
    """A general-engine run long enough to replay a captured graph on the CPU, with Warp's load of every module made
    to fail: the capture must not call it (the run loaded its own kernels before)."""
    import warp as wp
    import warp._src.context as wc

    from aca_warp.hf.loop import EngineTuning, run_hf
    from aca_warp.hf.options import RunOptions
    from aca_warp.scene import Record
    from aca_warp.studies.friction_stats import sector_scenes
    from aca_warp.studies.runs import batch_at_start

    def every_module(*args, **kwargs):
        if kwargs.get("modules") is None and (len(args) < 2 or args[1] is None):
            raise AssertionError("a capture forced the load of every imported module")
        return original(*args, **kwargs)

    original, captures = wc.force_load, []
    monkeypatch.setattr(wc, "force_load", every_module)

    class Counted(wp.ScopedCapture):
        def __enter__(self):
            captures.append(1)
            return super().__enter__()

    monkeypatch.setattr(wp, "ScopedCapture", Counted)
    model, state = batch_at_start(sector_scenes(1, 40), "cpu", "fp64")
    options = RunOptions(integrator="strang", engine="general", duration=1.2e-5, dt=2.5e-7, force=True)
    res = run_hf(model, state, options, record=Record(sample_dt=1e-6), tuning=EngineTuning(max_graph_steps=4))
    assert res.complete and captures


def test_the_script_writes_its_table(tmp_path, loads, monkeypatch):
    rows = [{"case": ["strang", "onchip", "mean", "plain"], "complete": True, "compile_s": 1.0, "wall_s": 2.0,
             "setup": [["a", 1]], "capture": [], "stepping": [["b", 64]]}]  # fmt: skip
    monkeypatch.setattr(loads, "run_cases", lambda cases, view=None, cache=None, device="cpu": rows)
    assert loads.main(["--out", str(tmp_path), "--labels", "new"]) == 0
    doc = json.loads((tmp_path / "kernel_loads.json").read_text())
    assert doc["rows"][0]["stepping"] == [["b", 64]] and doc["cold"] is False and doc["rows"][0]["checkout"] == "new"
    assert (
        "| new | strang, onchip, mean, plain | 1.00 | 2.00 | none | `b` (64) |"
        in (tmp_path / "kernel_loads.md").read_text()
    )


def test_a_failing_case_is_one_line_and_writes_nothing(tmp_path, loads, monkeypatch, capsys):
    def fail(cases, view=None, cache=None, device="cpu"):
        raise RuntimeError("the cases failed (exit 1): TypeError: an old checkout")

    monkeypatch.setattr(loads, "run_cases", fail)
    assert loads.main(["--out", str(tmp_path / "o")]) == 1
    assert "an old checkout" in capsys.readouterr().err and not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["{tmp}"], "not a checkout of aca_warp"),
        (["--device", "tpu:3"], "--device: device 'tpu:3'"),
        (["--cases", "strang:onchip:sometimes"], "invalid choice: 'strang:onchip:sometimes'"),
        (["--labels", "a", "b"], "--labels: give one name per checkout (1), got 2"),
    ],
)
def test_the_script_refuses_bad_input(tmp_path, loads, capsys, argv, said):
    with pytest.raises(SystemExit) as e:
        loads.main([a.format(tmp=tmp_path) for a in argv] + ["--out", str(tmp_path / "o")])
    assert e.value.code == 2 and said in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
