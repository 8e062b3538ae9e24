"""Property-based fuzzing of `aca-warp lf` scenes and `aca-warp sweep` specs (hypothesis, derandomized).

LF scene TOML (tables, ``[lf]`` constant overrides, ``[[schedule]]`` entries, snapshot times) and sweep specs
(``[sweep]`` name/base/mode/shard_size, ``[run]``, ``[parameters]`` lists and forms, inline and file base scenes)
go through ``aca_warp.cli.main`` in-process. Every outcome is one of: exit 2 with exactly one ``aca-warp: error:``
line on stderr and no output file, ``.partial`` or sweep directory; exit 0 with a complete file (LF) or a
directory whose every shard finished (sweep). Never a traceback, an uncaught exception, a hang or a stray file.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import h5py
import test_fuzz
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_fuzz import FLOATS, INTS, toml_text, toml_value

from aca_warp.cli import main
from aca_warp.lf.scene import _SEGMENT_KEYS
from aca_warp.lf.scene import _TABLES as LF_TABLES

FUZZ = settings(test_fuzz.FUZZ, max_examples=40)

# ------------------------------------------------------------------------------------------------ LF

LF_BASE: dict[str, dict] = {
    "scene": {"name": "lffuzz"},
    "pad": {"r_inner": 0.100, "r_outer": 0.104, "span_deg": 4.0},
    "patches": {"count": 4, "area_min": 2e-8, "area_max": 8e-8, "height": 3e-6, "seed": 1},
    "lf": {"capacity": 64, "p_birth": 1.0, "p_comp": 1e4},
    "snapshots": {"applications": True, "times": [0.01]},
}
LF_SCHEDULE = [
    {"kind": "application", "duration": 0.03, "normal_force": 50.0, "ramp": 0.01},
    {"kind": "pause", "duration": 0.01},
]
LF_STEPS = 4

lf_values = st.one_of(
    st.sampled_from(FLOATS),
    st.sampled_from(INTS),
    st.booleans(),
    st.text(max_size=4),
    st.sampled_from(["application", "pause", [0.01, "x"], [-1.0], {"a": 1}]),
)


def lf_text(doc: dict, schedule: object) -> str:
    text = toml_text(doc)
    if isinstance(schedule, list) and all(isinstance(s, dict) for s in schedule):
        for seg in schedule:
            text += "[[schedule]]\n" + "".join(f"{k} = {toml_value(v)}\n" for k, v in seg.items())
    else:
        text += f"schedule = {toml_value(schedule)}\n"  # a key of the last table, or a bare value
    return text


@st.composite
def lf_scenes(draw) -> tuple[dict, object]:
    doc = {k: dict(v) for k, v in LF_BASE.items()}
    sched: object = [dict(s) for s in LF_SCHEDULE]
    for _ in range(draw(st.integers(1, 3))):
        where = draw(st.sampled_from(["lf", "lf", "schedule", "schedule", "other", "bogus"]))
        if where == "schedule":
            ok = isinstance(sched, list) and sched and all(isinstance(x, dict) for x in sched)
            if not ok or draw(st.integers(0, 5)) == 0:
                sched = draw(st.sampled_from([[], 1.0, "x", [1, 2]]))
                continue
            i = draw(st.integers(0, len(sched) - 1))
            key = draw(st.sampled_from([*_SEGMENT_KEYS, "bogus"]))
            sched[i][key] = draw(lf_values)
        elif where == "bogus":
            doc.setdefault("bogus", {})["x"] = 1
        else:
            table = "lf" if where == "lf" else draw(st.sampled_from([t for t in LF_TABLES if t not in ("schedule",)]))
            key = draw(st.sampled_from([*LF_TABLES[table], "bogus_key"]))
            doc.setdefault(table, {})[key] = draw(lf_values)
    return doc, sched


def check_lf(code: int, err: str, out: Path) -> None:
    assert "Traceback" not in err
    assert not out.with_name(out.name + ".partial").exists(), "a .partial file was left behind"
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("aca-warp: error: "), err
        assert not out.exists(), "bad input wrote an LF file"
    else:
        assert code == 0, (code, err)
        with h5py.File(out, "r") as f:
            assert f.attrs["complete"] and f.attrs["kind"] == "lf" and "checkpoint" not in f


def run_lf_cli(text: str, tmp: Path, capsys, *extra: str) -> tuple[int, str, Path]:
    d = Path(tempfile.mkdtemp(dir=tmp))
    (d / "s.toml").write_text(text)
    out = d / "lf.h5"
    capsys.readouterr()
    code = main(["lf", str(d / "s.toml"), "-o", str(out), "--no-progress", "--duration", "0.04", *extra])
    return code, capsys.readouterr().err, out


def _lf(**tables) -> tuple[dict, list]:
    doc = {k: dict(v) for k, v in LF_BASE.items()}
    for t, v in tables.items():
        doc.setdefault(t, {}).update(v)
    return doc, [dict(s) for s in LF_SCHEDULE]


@FUZZ
@given(case=lf_scenes())
@example(case=_lf(lf={"capacity": 2**63 - 1}))
@example(case=_lf(lf={"contact_iterations": 2**63 - 1}))
@example(case=_lf(lf={"dt": 1e-300}))
@example(case=_lf(lf={"cell": 1e-300}))
@example(case=_lf(lf={"seed": 2**63 - 1}))
@example(case=_lf(pad={"r_outer": 1e300}))
@example(case=_lf(patches={"count": 10**6}))
@example(case=_lf(snapshots={"times": [1e300, -1.0]}))
@example(case=_lf(snapshots={"times": "0.1"}))
@example(case=({**LF_BASE}, [{"kind": "application", "duration": 1e300, "normal_force": 1.0}]))
@example(case=({**LF_BASE}, [{"kind": "application", "duration": 0.03, "pressure_bar": math.inf}]))
@example(case=({**LF_BASE}, [{"kind": "pause", "duration": 0.03}]))
@example(case=({**LF_BASE}, [{"kind": "application", "duration": 0.03, "normal_force": 1.0, "ramp": 0.05}]))
def test_fuzzed_lf_scenes(case, tmp_path, capsys):
    """Random [lf] overrides, [[schedule]] entries, snapshot times and tables in an otherwise valid tiny LF scene
    (4 steps when valid, with a checkpoint after every step)."""
    doc, sched = case
    check_lf(*run_lf_cli(lf_text(doc, sched), tmp_path, capsys, "--checkpoint-interval", "0.01"))


@settings(FUZZ, max_examples=15)
@given(text=st.text(max_size=50))
@example(text="[[schedule]]\nkind = 1\n")
@example(text="[lf]\n[lf]\n")
@example(text="schedule = 3\n")
def test_fuzzed_lf_toml_text(text, tmp_path, capsys):
    """Arbitrary text as an LF scene file: a parse error, an unknown key or table, or no schedule."""
    check_lf(*run_lf_cli(text, tmp_path, capsys))


def test_lf_resume_of_bad_files(tmp_path, capsys):
    """`lf --resume` and `rerun` of files that are not resumable LF runs: exit 2, one line, nothing changed."""
    junk = tmp_path / "junk.h5.partial"
    junk.write_bytes(b"not hdf5")
    hf_like = tmp_path / "hf.h5.partial"
    with h5py.File(hf_like, "w") as f:
        f.attrs["kind"] = "lf"
        f.attrs["scene"] = "{"
    for argv, message in (
        (["lf", "--resume", str(junk)], "is not an HDF5 file (expected an LF run file written by aca-warp)"),
        (["lf", "--resume", str(hf_like)], "attribute 'scene' is not valid JSON"),
        (["rerun", str(hf_like), "-o", str(tmp_path / "r.h5")], "attribute 'scene' is not valid JSON"),
    ):
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], (argv, err)
    assert junk.read_bytes() == b"not hdf5" and not (tmp_path / "r.h5").exists()


def test_inputs_that_are_not_regular_files(tmp_path, capsys):
    """A named pipe given as a run file (or an LF run file for --snapshot): exit 2 and one line saying it is not a
    regular file, with the article its kind takes; nothing written, and the pipe is never opened (which would block)."""
    import os

    pipe = tmp_path / "pipe.h5"
    os.mkfifo(pipe)
    out = tmp_path / "out.h5"
    run = "is not a regular file (expected a run file)"
    for argv, message in (
        (["analyze", str(pipe)], run),
        (["plot", str(pipe), "-o", str(tmp_path / "fig")], run),
        (["rerun", str(pipe), "-o", str(out)], run),
        (["hf", "--resume", str(pipe)], run),
        (["lf", "--resume", str(pipe)], run),
        (["hf", str(pipe), "--snapshot", "app1_end", "-o", str(out)], run.replace("a run", "an LF run")),
    ):
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], (argv, err)
    assert not out.exists() and not (tmp_path / "fig").exists()


# ------------------------------------------------------------------------------------------------ sweeps

HF_BASE = {
    "load": {"normal_force": 5.0},
    "patches": {"count": 3, "area_min": 2e-8, "area_max": 8e-8, "height": 3e-6, "seed": 1},
    "record": {"sample_dt": 1e-7},
    "run": {"duration": 2e-7},
}
SPEC: dict[str, dict] = {
    "sweep": {"name": "fz", "mode": "product", "shard_size": 2},
    "run": {"duration": 2e-7, "dt": 1e-8, "sample_dt": 1e-7},
    "parameters": {"friction.M": [0.7, 0.8]},
}
sweep_values = st.one_of(
    st.sampled_from([*FLOATS, *INTS]),
    st.booleans(),
    st.sampled_from(["product", "zip", "hf1", "strang", "fp32", "nope", "base.toml", "missing.toml", ""]),
    st.lists(st.sampled_from([0.5, 1, -1.0, math.nan, "x", True]), max_size=3),
    st.sampled_from(
        [
            {"linspace": [0.5, 0.9, 2]},
            {"linspace": [0.5, 0.9, 2**62]},
            {"geomspace": [0.0, 1.0, 2]},
            {"range": [1, 3]},
            {"range": [0, 2**62]},
            {"range": [1, 3, 0]},
            {"bogus": 1},
            {"linspace": [1, 2]},
        ]
    ),
)
PARAM_KEYS = [
    "friction.M", "load.normal_force", "patches.seed", "patches.count", "pad.span_deg", "initial.state",
    "growth.increment", "material.K_N", "disc.sliding_speed", "disc.angular_velocity", "bogus.key",
]  # fmt: skip


@st.composite
def sweep_specs(draw) -> dict:
    doc = {k: dict(v) for k, v in SPEC.items()}
    for _ in range(draw(st.integers(1, 3))):
        table = draw(st.sampled_from(["sweep", "run", "parameters", "parameters", "base", "bogus"]))
        if table == "sweep":
            key = draw(st.sampled_from(["name", "base", "mode", "shard_size", "bogus"]))
        elif table == "run":
            key = draw(st.sampled_from(["duration", "integrator", "precision", "dt", "tolerance", "sample_dt", "x"]))
            if key in ("duration", "dt"):  # only values that are refused or keep the run tiny
                doc["run"][key] = draw(st.sampled_from([math.nan, math.inf, -1.0, 0.0, 1e300, 1e-300, 4e-7, "x"]))
                continue
        elif table == "parameters":
            key = draw(st.sampled_from(PARAM_KEYS))
        elif table == "base":
            doc.setdefault("base", {})[draw(st.sampled_from(["friction", "load", "patches", "bogus"]))] = {
                draw(st.sampled_from(["M", "normal_force", "count", "x"])): draw(sweep_values)
            }
            continue
        else:
            key = "x"
        doc.setdefault(table, {})[key] = draw(sweep_values)
    return doc


def sweep_text(doc: dict) -> str:
    text = ""
    for table, tab in doc.items():
        if table == "base":
            for sub, vals in tab.items():
                text += f"[base.{sub}]\n" + "".join(f"{k} = {toml_value(v)}\n" for k, v in vals.items())
        else:
            text += f"[{table}]\n" + "".join(f'"{k}" = {toml_value(v)}\n' for k, v in tab.items())
    return text


def run_sweep_cli(doc: dict, tmp: Path, capsys) -> tuple[int, str, Path]:
    d = Path(tempfile.mkdtemp(dir=tmp))
    (d / "base.toml").write_text(toml_text(HF_BASE))
    doc = {**doc, "sweep": {"base": "base.toml", **doc.get("sweep", {})}}
    (d / "spec.toml").write_text(sweep_text(doc))
    out = d / "out"
    capsys.readouterr()
    code = main(["sweep", str(d / "spec.toml"), "-o", str(out), "--workers", "0", "--quiet"])
    return code, capsys.readouterr().err, out


def check_sweep(code: int, err: str, out: Path) -> None:
    assert "Traceback" not in err
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("aca-warp: error: "), err
        assert not out.exists(), "bad input left a sweep directory"
    else:
        assert code in (0, 3), (code, err)  # 3: a pad stopped on a fault (extreme but valid values)
        assert (out / "manifest.json").is_file() and not list(out.glob("*.partial"))


@FUZZ
@given(doc=sweep_specs())
@example(doc={**SPEC, "parameters": {"friction.M": {"range": [0, 2**62]}}})
@example(doc={**SPEC, "parameters": {"friction.M": {"linspace": [0.5, 0.9, 2**62]}}})
@example(doc={**SPEC, "parameters": {"friction.M": [0.5] * 30, "load.normal_force": [1.0] * 30,
                                     "patches.seed": list(range(30)), "initial.seed": list(range(30)),
                                     "material.K_N": [1e9] * 30}})  # fmt: skip
@example(doc={**SPEC, "parameters": {"patches.count": [3, 0]}})
@example(doc={**SPEC, "parameters": {"patches.count": [3, 2, 10**9]}})
@example(doc={**SPEC, "run": {"duration": 1e300}})
@example(doc={**SPEC, "run": {"duration": 2e-7, "sample_dt": 1e-300}})
@example(doc={**SPEC, "sweep": {"base": "missing.toml"}})
@example(doc={**SPEC, "sweep": {"base": "hf1", "shard_size": 0}})
@example(doc={**SPEC, "base": {"patches": {"count": -1}}})
@example(doc={**SPEC, "parameters": {"pad.span_deg": [1.0, 20.0, 0.05]}})
def test_fuzzed_sweep_specs(doc, tmp_path, capsys):
    """Random [sweep], [run], [parameters] and [base] entries in an otherwise valid 2-pad sweep of a tiny scene."""
    check_sweep(*run_sweep_cli(doc, tmp_path, capsys))


def test_sweep_output_rules(tmp_path, capsys):
    """A sweep directory holding another sweep needs --overwrite; a file where DIR should be is refused; the same
    spec again skips its finished shards (a sweep resumes by design); a .partial shard is rerun."""
    code, err, out = run_sweep_cli(SPEC, tmp_path, capsys)
    assert code == 0, err
    spec = out.parent / "spec.toml"
    other = out.parent / "other.toml"
    other.write_text(spec.read_text().replace("0.8]", "0.9]"))
    for argv, message in (
        (["sweep", str(other), "-o", str(out), "--workers", "0", "--quiet"], "pass --overwrite"),
        (["sweep", str(spec), "-o", str(spec), "--workers", "0", "--quiet"], "exists and is not a folder"),
    ):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    before = (out / "shard-00000.h5").read_bytes()
    (out / "shard-00000.h5").rename(out / "shard-00000.h5.partial")  # as a killed worker leaves it
    assert main(["sweep", str(spec), "-o", str(out), "--workers", "0", "--quiet"]) == 0
    assert (out / "shard-00000.h5").is_file() and not (out / "shard-00000.h5.partial").exists()
    with h5py.File(out / "shard-00000.h5", "r") as f:
        assert f.attrs["complete"] and len(before) > 0
    assert main(["sweep", str(other), "-o", str(out), "--workers", "0", "--quiet", "--overwrite"]) == 0
