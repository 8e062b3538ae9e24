"""scripts/time_varying_area.py: the commands it times and its refusal of bad input (no run here)."""

from __future__ import annotations

import pytest
from scriptload import load_script


def load():
    return load_script("time_varying_area")


def test_dry_run_prints_one_command_per_step(capsys):
    assert load().main(["--dry-run", "--steps", "5e-8", "2.5e-7", "--duration", "0.01", "--device", "cpu"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2
    assert lines[0].startswith("aca-warp hf varying_area --duration 0.01 --dt 5e-08 --precision fp32 --device cpu")
    assert "--dt 2.5e-07" in lines[1] and lines[1].endswith("va_2.5e-07.h5")


def test_math_fast_adds_the_fast_math_command_per_step(capsys):
    assert load().main(["--dry-run", "--steps", "5e-8", "--math", "exact", "fast"]) == 0
    exact, fast = capsys.readouterr().out.splitlines()
    assert exact.endswith("va_5e-08.h5") and fast.endswith("va_5e-08_fast.h5 --fast-math")


def test_growth_dt_gives_each_step_each_spacing(capsys):
    """``default`` is no option (the command's default spacing); a number is passed as --growth-dt and names the run
    file; ``scene``, which named the scene's clock when that was the default, is refused with the number to give."""
    assert load().main(["--dry-run", "--steps", "5e-8", "1e-7", "--growth-dt", "default", "1e-6"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4 and "--growth-dt" not in lines[0] and lines[0].endswith("va_5e-08.h5")
    assert lines[1].endswith("va_5e-08_g1e-06.h5 --growth-dt 1e-06")
    assert lines[3].endswith("va_1e-07_g1e-06.h5 --growth-dt 1e-06")
    with pytest.raises(SystemExit) as e:
        load().main(["--dry-run", "--growth-dt", "scene"])
    assert e.value.code == 2 and "give the scene's interval (2.02e-7 s" in capsys.readouterr().err


def test_default_step_is_no_option_and_read_back(capsys, tmp_path):
    """``--steps default`` times the command without --dt; the row keeps the step its run file names."""
    import h5py

    assert load().main(["--dry-run", "--steps", "default", "5e-8"]) == 0
    default, fixed = capsys.readouterr().out.splitlines()
    assert "--dt" not in default and default.endswith("va_default.h5") and "--dt 5e-08" in fixed
    run = tmp_path / "va_default.h5"
    with h5py.File(run, "w") as f:
        f.attrs["run_options"] = '{"dt": 1e-07, "growth_dt": 5e-06}'
    used = load().settings_used(run)
    assert used == {"step_used_s": 1e-7, "growth_dt_used_s": 5e-6}
    assert load().settings_used(tmp_path / "missing.h5") == {"step_used_s": None, "growth_dt_used_s": None}
    doc = {"date": "d", "machine": "m", "device": "cuda:0", "duration_s": 0.36,
           "rows": [{"step_s": None, **used, "wall_s": 14.7, "exit": 0, "summary": "ok"}]}  # fmt: skip
    assert "| default (1e-07) | exact | default (5e-06) | 14.7 | 0 | ok |" in load().markdown(doc)


@pytest.mark.parametrize("argv", [["--steps", "-1e-7"], ["--duration", "0"], ["--growth-dt", "0"]])
def test_bad_input_is_one_line_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as e:
        load().main(["--dry-run", *argv])
    assert e.value.code == 2
    assert "must be positive" in capsys.readouterr().err


def test_markdown_has_a_row_per_step():
    doc = {"date": "d", "machine": "m", "device": "cuda:0", "duration_s": 0.36,
           "rows": [{"step_s": 1e-7, "wall_s": 46.6, "exit": 0, "summary": "ok"}]}  # fmt: skip
    assert "| 1e-07 | exact | scene | 46.6 | 0 | ok |" in load().markdown(doc)
    doc["rows"].append({"step_s": 1e-7, "fast_math": True, "wall_s": 40.0, "exit": 0, "summary": "ok"})
    assert "| 1e-07 | fast | scene | 40.0 | 0 | ok |" in load().markdown(doc)
    doc["rows"].append({"step_s": 1e-7, "growth_dt_s": 1e-6, "wall_s": 20.0, "exit": 0, "summary": "ok"})
    assert "| 1e-07 | exact | 1e-06 | 20.0 | 0 | ok |" in load().markdown(doc)
    doc["rows"].append({"step_s": 5e-8, "growth_dt_used_s": 5e-6, "wall_s": 23.0, "exit": 0, "summary": "ok"})
    assert "| 5e-08 | exact | default (5e-06) | 23.0 | 0 | ok |" in load().markdown(doc)


def test_machine_is_read_from_the_run_file(tmp_path):
    """The timed runs are subprocesses: the device they ran on is the one their run file names."""
    import h5py

    run = tmp_path / "va_5e-08.h5"
    with h5py.File(run, "w") as f:
        f.attrs.update(device_name="NVIDIA H200", host="Xeon, 16 cores")
    assert load().machine_of(run) == "NVIDIA H200; host Xeon, 16 cores"
    assert load().machine_of(tmp_path / "missing.h5")  # falls back to this host's name


def test_checkouts_run_each_case_from_both(capsys, tmp_path):
    base = tmp_path / "base"
    for need in ("aca_warp/__init__.py", "kernels/__init__.py"):
        (base / need).parent.mkdir(parents=True, exist_ok=True)
        (base / need).write_text("")
    assert load().main(["--dry-run", "--steps", "5e-8", "--checkouts", str(base), "."]) == 0
    first, second = capsys.readouterr().out.splitlines()
    assert first.endswith("va_5e-08_c0.h5") and second.endswith("va_5e-08_c1.h5")


@pytest.mark.parametrize(
    ("argv", "message"),
    [(["--repeat", "2"], "--repeat needs --checkouts"), (["--checkouts", "nowhere", "."], "not a checkout")],
)
def test_checkouts_refusals_are_one_line_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as e:
        load().main(["--dry-run", *argv])
    assert e.value.code == 2
    assert message in capsys.readouterr().err


def test_markdown_of_two_checkouts_names_them_and_the_comparison():
    doc = {"date": "d", "machine": "m", "device": "cuda:0", "duration_s": 0.36, "checkouts": ["old", "new"],
           "rows": [{"step_s": 5e-8, "checkout": 1, "wall_s": 40.0, "exit": 0, "summary": "ok"}],
           "comparisons": [{"step_s": 5e-8, "fast_math": False, "identical": True, "differ": []}]}  # fmt: skip
    md = load().markdown(doc)
    assert "0 = `old`, 1 = `new`" in md and "| 5e-08 | exact | scene | 1 | 40.0 | 0 | ok |" in md
    assert "5e-08 s, exact, events scene: the two records bit-identical" in md


def test_markdown_names_the_default_step_of_a_comparison():
    """A comparison of the command's default step names the step its run file read back."""
    doc = {"date": "d", "machine": "m", "device": "cuda:0", "duration_s": 0.36, "checkouts": ["old", "new"],
           "rows": [{"step_s": None, "step_used_s": 1e-7, "growth_dt_s": None, "growth_dt_used_s": 5e-6,
                     "checkout": 1, "wall_s": 14.7, "exit": 0, "summary": "ok"}],
           "comparisons": [{"step_s": None, "step_used_s": 1e-7, "growth_dt_s": None, "growth_dt_used_s": 5e-6,
                            "fast_math": False, "identical": True, "differ": []}]}  # fmt: skip
    md = load().markdown(doc)
    assert "| default (1e-07) | exact | default (5e-06) | 1 | 14.7 | 0 | ok |" in md
    assert "* default (1e-07) s, exact, events default (5e-06): the two records bit-identical" in md


def test_run_files_compared_dataset_by_dataset(tmp_path):
    """Two checkouts' records: identical when every dataset is in both and the same; a dataset that differs or is
    missing from one file is named."""
    import h5py
    import numpy as np

    def write(name, **datasets):
        with h5py.File(tmp_path / name, "w") as f:
            for key, value in datasets.items():
                f[key] = value
        return tmp_path / name

    a = write("a.h5", mu=np.arange(3.0), u=np.ones(2))
    assert load().compare_runs(a, write("b.h5", mu=np.arange(3.0), u=np.ones(2))) == {"identical": True, "differ": []}
    changed = load().compare_runs(a, write("c.h5", mu=np.array([0.0, 1.0, np.nextafter(2.0, 3.0)]), u=np.ones(2)))
    assert changed == {"identical": False, "differ": ["mu"]}
    assert load().compare_runs(a, write("d.h5", mu=np.arange(3.0))) == {"identical": False, "differ": ["u"]}
