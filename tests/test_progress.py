"""Progress where no terminal shows a bar (``aca_warp.common.progress``): a line every interval of wall time, none
before it, on both engines' runs when stderr (HF) or stdout (LF) is not a terminal."""

from __future__ import annotations

import io

import pytest

from aca_warp.common import progress as P


def test_log_progress_prints_one_line_per_interval():
    now = [0.0]
    out = io.StringIO()
    calls = []

    def rate() -> str:
        calls.append(1)
        return "mu 0.500"

    log = P.LogProgress("hf:", 0.01, interval=30.0, clock=lambda: now[0], stream=out)
    now[0] = 29.0
    assert not log.update(0.001, rate) and not calls  # not due: the rate is not even made
    now[0] = 31.0
    assert log.update(0.0042, rate) and calls == [1]
    now[0] = 40.0
    assert not log.update(0.005, "x")  # 9 s after the last line
    now[0] = 61.5
    assert log.update(0.01, "1.2e+05 steps/s")
    assert out.getvalue().splitlines() == [
        "aca-warp: hf: 0.0042 of 0.01 s simulated (42 %), mu 0.500, 31 s elapsed",
        "aca-warp: hf: 0.01 of 0.01 s simulated (100 %), 1.2e+05 steps/s, 62 s elapsed",
    ]


@pytest.mark.parametrize("progress", [True, False])
def test_hf_run_logs_progress_off_a_terminal(progress, tmp_path, monkeypatch, capsys):
    """An HF run with stderr captured (not a terminal) writes progress lines when due, none with progress off."""
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.runner import run_scene
    from aca_warp.scene import Pad, PatchGenerator, Record, Scene

    monkeypatch.setattr(P, "LOG_INTERVAL", 0.0)
    pad = Pad()
    scene = Scene(name="small", pad=pad, patches=PatchGenerator(count=20, seed=4).generate(pad), normal_force=20.0,
                  record=Record(sample_dt=1e-7), duration=2e-5)  # fmt: skip
    run_scene(scene, tmp_path / "run.h5", RunOptions(dt=1e-8), device="cpu", progress=progress)
    lines = [x for x in capsys.readouterr().err.splitlines() if x.startswith("aca-warp: hf:")]
    assert bool(lines) == progress
    if progress:
        assert lines[-1].startswith("aca-warp: hf: 2e-05 of 2e-05 s simulated (100 %), ") and "steps/s" in lines[-1]
