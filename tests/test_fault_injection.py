"""scripts/fault_injection.py: its quick mode kills an HF run at random, resumes it, compares with the
uninterrupted run and writes the counts as JSON and Markdown; a corrupted recovery is reported, not passed."""

from __future__ import annotations

import json
import subprocess
import sys

from scriptload import SCRIPTS, load_script


def test_quick_hf_trial(tmp_path) -> None:
    fi = load_script("fault_injection")
    js, md = tmp_path / "fi.json", tmp_path / "fi.md"
    argv = ["--quick", "--workloads", "hf", "--max-kills", "1", "--dir", str(tmp_path / "w")]
    assert fi.main([*argv, "--json", str(js), "--markdown", str(md)]) == 0
    s = json.loads(js.read_text())
    hf = s["workloads"]["hf"]
    assert hf["trials"] == 1 and hf["identical"] == 1 and hf["different"] == hf["errors"] == 0
    assert s["failures"] == [] and "| hf | 1 |" in md.read_text()


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


def test_help() -> None:
    r = subprocess.run([sys.executable, str(SCRIPTS / "fault_injection.py"), "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "--quick" in r.stdout and "SIGKILL" in r.stdout
