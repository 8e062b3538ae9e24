"""Property-based fuzzing of the inputs of `aca-warp hf` (hypothesis, derandomized: the same examples every run).

Scene TOML text (broken syntax, unknown tables and keys, wrongly typed and extreme values) and HDF5 patch files
(missing datasets, groups for datasets, wrong shapes and dtypes, NaN, negative areas, empty, not HDF5) go through
``aca_warp.cli.main`` in-process, two through a subprocess. Every outcome is one of: exit 2 with exactly one
``aca-warp: error:`` line on stderr and no output file (nor ``.partial``); exit 0 with a complete run file; exit 3
(a fault) with an incomplete, readable file. Never a traceback, an uncaught exception or a stray file.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from aca_warp.cli import main
from aca_warp.scene.files import _TABLES

FUZZ = settings(
    derandomize=True,
    deadline=None,
    database=None,
    max_examples=30,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
RUN = ["--no-progress", "--duration", "2e-7"]  # 2 samples, 20 steps when the input is valid

BASE: dict[str, dict] = {
    "scene": {"name": "fuzz"},
    "load": {"normal_force": 5.0},
    "patches": {"count": 4, "area_min": 2e-8, "area_max": 8e-8, "height": 3e-6, "seed": 1},
    "record": {"sample_dt": 1e-7},
    "run": {"duration": 2e-7},
}
FLOATS = [math.nan, math.inf, -math.inf, -1.0, -0.0, 0.0, 1e-300, 2e-8, 0.5, 3.0, 1e300]
INTS = [-1, 0, 1, 3, 2**63 - 1, -(2**63)]


def toml_value(v: object) -> str:
    """TOML text of a value (strings, numbers, booleans, arrays, inline tables)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


def toml_text(doc: dict[str, dict]) -> str:
    return "".join(
        f"[{t}]\n" + "".join(f"{json.dumps(k)} = {toml_value(v)}\n" for k, v in tab.items()) for t, tab in doc.items()
    )


values = st.one_of(
    st.sampled_from(FLOATS),
    st.sampled_from(INTS),
    st.booleans(),
    st.text(max_size=6),
    st.sampled_from(["velocity", "rest", "equilibrium", "patches.h5"]),
    st.lists(st.sampled_from([0.0, 1e-7, -1.0, "velocity", 2]), max_size=3),
    st.dictionaries(st.sampled_from(["a", "count"]), st.integers(0, 3), max_size=2),
)
tables = st.sampled_from([*_TABLES, "bogus"])


@st.composite
def mutated_scenes(draw) -> dict[str, dict]:
    doc = {k: dict(v) for k, v in BASE.items()}
    for _ in range(draw(st.integers(1, 3))):
        table = draw(tables)
        keys = [*_TABLES.get(table, ()), "bogus_key"]
        key = draw(st.sampled_from(keys))
        if draw(st.integers(0, 4)) == 0 and key in doc.get(table, {}):
            del doc[table][key]
        else:
            doc.setdefault(table, {})[key] = draw(values)
    return doc


def check_outcome(code: int, err: str, out: Path) -> None:
    """The contract of the module docstring for one invocation."""
    assert "Traceback" not in err
    part = out.with_name(out.name + ".partial")
    assert not part.exists(), "a .partial file was left behind"
    if code == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("aca-warp: error: "), err
        assert not out.exists(), "bad input wrote a run file"
    elif code == 0:
        with h5py.File(out, "r") as f:
            assert f.attrs["complete"] and len(f["global/mu"]) == 3
    else:
        assert code == 3, code
        assert "aca-warp: run stopped:" in err
        with h5py.File(out, "r") as f:
            assert not f.attrs["complete"]


def run_cli(scene_text: str | None, tmp: Path, capsys, patch_writer=None) -> tuple[int, str, Path]:
    d = Path(tempfile.mkdtemp(dir=tmp))
    if patch_writer is not None:
        patch_writer(d / "patches.h5")
    (d / "s.toml").write_text(scene_text or "")
    out = d / "run.h5"
    capsys.readouterr()
    code = main(["hf", str(d / "s.toml"), "-o", str(out), *RUN])
    return code, capsys.readouterr().err, out


@FUZZ
@given(doc=mutated_scenes())
@example(doc={**BASE, "patches": {"count": 2**63 - 1}})
@example(doc={**BASE, "patches": {"count": 10**8}})
@example(doc={**BASE, "record": {"sample_dt": 1e-300}})
@example(doc={**BASE, "record": {"window": [1.0, "x"]}})
@example(doc={**BASE, "pad": {"r_inner": 0.2}})
@example(doc={**BASE, "load": {"normal_force": 1e300}})
def test_fuzzed_scene_tables(doc, tmp_path, capsys):
    """Random tables, keys and values in an otherwise valid tiny scene."""
    check_outcome(*run_cli(toml_text(doc), tmp_path, capsys))


@settings(FUZZ, max_examples=20)
@given(text=st.text(max_size=60) | st.binary(max_size=40).map(lambda b: b.decode("latin-1")))
@example(text="[patches\ncount = 4")
@example(text='[run]\nduration = "1e-6"')
@example(text="[[record]]\nsample_dt = 1e-7")
@example(text="a = 1\n[scene]\n")
@example(text="[scene]\nname = 1\n[scene]\nname = 2\n")
def test_fuzzed_toml_text(text, tmp_path, capsys):
    """Arbitrary text as a scene file: a parse error, an unknown key or table, or (empty text) the defaults."""
    if not text.strip():
        text = "[run]\nduration = 2e-7\n[patches]\ncount = 3\n"  # the all-defaults scene runs a 1758-patch pad
    check_outcome(*run_cli(text, tmp_path, capsys))


GOOD = {
    "x": np.array([-2e-3, 0.0, 2e-3]),
    "y": np.array([0.13, 0.13, 0.13]),
    "area": np.array([4e-8, 5e-8, 6e-8]),
    "height": np.full(3, 3e-6),
}
BAD_DATA = st.sampled_from(
    [
        "missing",
        "group",
        "2d",
        "scalar",
        "empty",
        "nan",
        "negative",
        "strings",
        "ints",
        "compound",
        "short",
        "huge",
        "good",
    ]
)


def write_patches(path: Path, recipe: dict[str, str]) -> None:
    with h5py.File(path, "w") as f:
        for name, good in GOOD.items():
            how = recipe.get(name, "good")
            if how == "missing":
                continue
            if how == "group":
                f.create_group(name)
                continue
            data = {
                "2d": np.tile(good, (2, 1)),
                "scalar": np.float64(good[0]),
                "empty": np.zeros(0),
                "nan": np.where(np.arange(3) == 1, np.nan, good),
                "negative": -good,
                "strings": np.array([b"a", b"b", b"c"]),
                "ints": np.array([1, 2, 3], dtype=np.int64),
                "compound": np.zeros(3, dtype=[("a", "f8"), ("b", "i4")]),
                "short": good[:2],
                "huge": good * 1e200,
                "good": good,
            }[how]
            f.create_dataset(name, data=data)


@settings(FUZZ, max_examples=25)
@given(recipe=st.dictionaries(st.sampled_from(sorted(GOOD)), BAD_DATA, min_size=1, max_size=3))
@example(recipe={"area": "negative"})
@example(recipe={"x": "compound"})
@example(recipe={"y": "strings"})
@example(recipe={"height": "group"})
def test_fuzzed_patch_files(recipe, tmp_path, capsys):
    """A [patches] file = "patches.h5" scene whose HDF5 file has broken datasets."""
    text = toml_text({**BASE, "patches": {"file": "patches.h5"}})
    check_outcome(*run_cli(text, tmp_path, capsys, lambda p: write_patches(p, recipe)))


def test_not_hdf5_and_subprocess(tmp_path, capsys):
    """A patch file that is not HDF5 (in-process), and through the real console entry point in a subprocess: a
    broken TOML and a patch file with a NaN: exit 2, one line, no traceback, no file."""
    code, err, out = run_cli(
        toml_text({**BASE, "patches": {"file": "patches.h5"}}),
        tmp_path,
        capsys,
        lambda p: p.write_bytes(b"\x89HDF not really\n" * 10),
    )
    check_outcome(code, err, out)
    assert code == 2 and "cannot read patch file" in err
    env = dict(os.environ)
    (tmp_path / "broken.toml").write_text("[load\nnormal_force = 1")
    write_patches(tmp_path / "patches.h5", {"x": "nan"})
    (tmp_path / "nan.toml").write_text(toml_text({**BASE, "patches": {"file": "patches.h5"}}))
    for scene, message in (("broken.toml", "cannot parse"), ("nan.toml", "non-finite")):
        out = tmp_path / f"{scene}.h5"
        cmd = [sys.executable, "-m", "aca_warp.cli", "hf", str(tmp_path / scene), "-o", str(out), *RUN]
        p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
        err = "\n".join(line for line in p.stderr.splitlines() if not line.startswith("Warp CUDA warning"))
        check_outcome(p.returncode, err, out)
        assert p.returncode == 2 and message in err
