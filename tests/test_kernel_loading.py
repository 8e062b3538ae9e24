"""Every kernel a run launches is loaded in its set-up, before the clock of its stepping starts: a module first loaded
at its first launch would put its compile (seconds on an empty kernel cache) into ``RunResult.wall_time``, the
stepping time that the studies' work-precision and the benchmarks compare, and leave it out of ``compile_time``.

``scripts/kernel_loads.py`` runs every engine and integrator on a one-pad sector in a process of its own, each case
after every Warp module was unloaded, and lists the modules loaded while the run stepped."""

from __future__ import annotations

import json

import pytest
from scriptload import load_script


@pytest.fixture(scope="module")
def loads():
    return load_script("kernel_loads")


def test_a_run_loads_every_kernel_it_launches_before_its_stepping(loads):
    rows = loads.run_cases(loads.CASES)
    assert [tuple(r["case"]) for r in rows] == loads.CASES
    for r in rows:
        assert r["complete"], r
        assert r["setup"], r  # the spy sees loads: every run loads its kernels again after the unloading
        assert r["stepping"] == [], f"{r['case']}: loaded while stepping: {r['stepping']}"
    by_case = {tuple(r["case"]): r["setup"] for r in rows}
    # the treatment's closing kernel, not its stepping ones, on chip; the split step's module only where it runs
    assert any("strang_close" in name for name in by_case["strang", "onchip", "mean"])
    assert not any("strang_advance" in name for name in by_case["strang", "onchip", "mean"])
    assert any("strang_advance" in name for name in by_case["strang", "general", "mean"])
    assert "aca_warp.kernels.hf_controlled" in by_case["auto", "general", "point"]
    assert "aca_warp.kernels.hf_controlled" not in by_case["adaptive", "general", "point"]


def test_the_script_writes_its_table(tmp_path, loads, monkeypatch):
    rows = [{"case": ["strang", "onchip", "mean"], "complete": True, "compile_s": 1.0, "wall_s": 2.0, "setup": ["a"],
             "stepping": ["b"]}]  # fmt: skip
    monkeypatch.setattr(loads, "run_cases", lambda cases, view=None, cache=None, device="cpu": rows)
    assert loads.main(["--out", str(tmp_path)]) == 0
    doc = json.loads((tmp_path / "kernel_loads.json").read_text())
    assert doc["rows"][0]["stepping"] == ["b"] and doc["cold"] is False
    assert "| strang, onchip, mean | 1.00 | 2.00 | `b` |" in (tmp_path / "kernel_loads.md").read_text()


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["{tmp}"], "not a checkout of aca_warp"),
        (["--device", "tpu:3"], "--device: device 'tpu:3'"),
        (["--cases", "strang:onchip:sometimes"], "invalid choice: 'strang:onchip:sometimes'"),
    ],
)
def test_the_script_refuses_bad_input(tmp_path, loads, capsys, argv, said):
    with pytest.raises(SystemExit) as e:
        loads.main([a.format(tmp=tmp_path) for a in argv] + ["--out", str(tmp_path / "o")])
    assert e.value.code == 2 and said in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
