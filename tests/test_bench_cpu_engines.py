"""``scripts/bench_cpu_engines.py``: both engines on a small CPU case, their bits compared; bad cases refused."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scriptload import load_script


def test_small_case_runs_both_engines_bit_identical(tmp_path: Path) -> None:
    out, md = tmp_path / "b.json", tmp_path / "b.md"
    args = ["--cases", "sector20", "--duration", "4e-6", "--repeats", "1", "--json", str(out), "--markdown", str(md)]
    assert load_script("bench_cpu_engines").main(args) == 0
    (row,) = json.loads(out.read_text())["results"]
    assert (row["case"], row["pads"], row["patches"], row["precision"]) == ("sector20", 1, 20, "fp64")
    assert (
        row["steps"] == 80
        and row["step_s"] == 5e-8
        and row["bit_identical"]
        and set(row["us_per_step"]) == {"general", "onchip"}
    )
    assert row["speedup"] == pytest.approx(min(row["walls"]["general"]) / min(row["walls"]["onchip"]))
    assert "| sector20 | 1 | 20 | fp64 | 5e-08 | 80 |" in md.read_text()


def test_an_engine_that_parts_from_the_other_stops_the_script(monkeypatch, capsys) -> None:
    """A run whose μ(t) differs between the engines ends the script with exit code 1 and one line."""
    mod = load_script("bench_cpu_engines")
    real = mod.time_engine

    def parted(scenes, engine, *a):
        r = real(scenes, engine, *a)
        if engine == "onchip":
            r["mu"] = r["mu"] + 1e-15
        return r

    monkeypatch.setattr(mod, "time_engine", parted)
    assert mod.main(["--cases", "sector20", "--duration", "2e-6", "--repeats", "1"]) == 1
    assert "differs from the general one's" in capsys.readouterr().err


@pytest.mark.parametrize("case", ["hf9", "sector", "sectors4", "varying_area2"])
def test_unknown_cases_are_refused_before_anything_runs(case: str, tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as e:
        load_script("bench_cpu_engines").main(["--cases", case, "--json", str(tmp_path / "x.json")])
    assert e.value.code == 2 and not (tmp_path / "x.json").exists()
