"""scripts/fault_injection.py: its quick mode kills an HF run at random, resumes it, compares with the
uninterrupted run and writes the counts as JSON and Markdown; a corrupted recovery is reported, not passed."""

from __future__ import annotations

import json

import pytest
from scriptload import load_script


def test_quick_hf_trial(tmp_path) -> None:
    fi = load_script("fault_injection")
    js, md = tmp_path / "fi.json", tmp_path / "fi.md"
    argv = ["--quick", "--workloads", "hf", "--max-kills", "1", "--dir", str(tmp_path / "w")]
    assert fi.main([*argv, "--json", str(js), "--markdown", str(md)]) == 0
    s = json.loads(js.read_text())
    hf = s["workloads"]["hf"]
    assert hf["trials"] == 1 and hf["identical"] == 1 and hf["different"] == hf["errors"] == 0
    assert s["failures"] == [] and "| hf | 1 |" in md.read_text()


def test_quick_interrupt_trials(tmp_path) -> None:
    """--signals INT,TERM: the kill of an LF run is Ctrl-C or SIGTERM, which ends it with one line and exit
    130/143 (checked by the script), and --resume of the interrupted file ends bit-identical (HF runs:
    test_cli_faults.py)."""
    fi = load_script("fault_injection")
    js = tmp_path / "fi.json"
    argv = ["--quick", "--workloads", "lf", "--max-kills", "1", "--signals", "INT,TERM", "--seed", "3"]
    assert fi.main([*argv, "--dir", str(tmp_path / "w"), "--json", str(js)]) == 0
    s = json.loads(js.read_text())
    for name in ("lf",):
        w = s["workloads"][name]
        assert w["identical"] == w["trials"] == 1 and w["signals"]["KILL"] == 0, w
    assert s["failures"] == []


def test_interrupt_outcomes_are_judged() -> None:
    """One line and 128 + signal pass; a traceback, two lines or another exit code fail; exit 0 is a run that
    finished first."""
    import signal

    fi = load_script("fault_injection")
    line = "aca-warp: interrupted (SIGTERM); run.h5 keeps the samples ..."
    assert fi.interrupted(143, line + "\n", signal.SIGTERM) == (True, 143, line + "\n")
    assert fi.interrupted(0, "", signal.SIGINT)[0] is False
    assert fi.interrupted(-15, "", signal.SIGTERM)[1] == -1  # before the handlers: early
    for code, err in ((143, "Traceback (most recent call last):\n" + line), (1, "aca-warp: error: x"), (130, "")):
        try:
            fi.interrupted(code, err, signal.SIGTERM if code != 130 else signal.SIGINT)
        except RuntimeError:
            continue
        raise AssertionError(f"accepted exit {code}: {err!r}")


def test_a_different_output_is_reported(tmp_path) -> None:
    """The comparison sees one changed value (a trial's output against the reference)."""
    fi = load_script("fault_injection")
    import h5py
    import numpy as np

    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    for p, v in ((a, 1.0), (b, np.nextafter(1.0, 2.0))):
        with h5py.File(p, "w") as f:
            f["global/mu"] = np.array([0.5, v])
    assert fi.datasets(a) != fi.datasets(b) and fi.datasets(a) == fi.datasets(a)


def test_help(capsys) -> None:
    """The script's help (loaded as the script, run in this process)."""
    with pytest.raises(SystemExit) as done:
        load_script("fault_injection").main(["--help"])
    out = capsys.readouterr().out
    assert done.value.code == 0 and "--quick" in out and "SIGKILL" in out
