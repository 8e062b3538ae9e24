"""Sweeps: spec expansion, shard files, resume after a kill, refusal of a foreign spec, Dask == serial bit for bit."""

from __future__ import annotations

import ipaddress
import json
import os
import re
from pathlib import Path

import h5py
import numpy as np
import psutil
import pytest
from procs import small_sweep_doc
from test_fuzz import toml_text

from aca_warp.cli import main
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import RunOptions
from aca_warp.hf.recorder import GLOBAL_NAMES
from aca_warp.hf.state import initial_state
from aca_warp.scene import Friction, PatchGenerator, preset
from aca_warp.sweep import SweepError, load_spec, load_sweep, run_sweep
from aca_warp.sweep.prepare import run_options

# 2 M x 3 loads x 2 seeds = 12 pads of 25 patches, 4 shards of 3; 4 µs simulated (5 samples).
TINY = small_sweep_doc(
    "tiny",
    count=25,
    duration=4e-6,
    parameters={
        "friction.M": [0.6, 0.8],
        "load.normal_force": {"linspace": [300.0, 500.0, 3]},
        "patches.seed": {"range": [1, 3]},
    },
)


def _spec(**changes):
    doc = json.loads(json.dumps(TINY))
    for k, v in changes.items():
        table, key = k.split("__")
        doc[table][key] = v
    return load_spec(doc, base_dir=Path.cwd())


def _outputs(d: Path) -> dict:
    s = load_sweep(d)
    return {k: s[k] for k in ("time", *GLOBAL_NAMES)} | {f"p:{k}": v for k, v in s["parameters"].items()}


def _assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert np.array_equal(a[k], b[k]), k


def test_spec_expansion_and_errors() -> None:
    s = _spec()
    assert (s.pad_count, s.shard_count, s.shard_range(3)) == (12, 4, (9, 12))
    assert s.parameters["load.normal_force"][:3] == [300.0, 300.0, 400.0]  # product: last key varies fastest
    assert s.parameters["patches.seed"][:4] == [1, 2, 1, 2]
    sc = s.scene(11)
    assert (sc.friction.M, sc.normal_force, sc.patches.count) == (0.8, 500.0, 25)
    assert "seed=2" in sc.patches.source
    z = load_spec(
        {
            "sweep": {"base": "hf1", "mode": "zip"},
            "parameters": {"friction.M": [0.5, 0.7], "disc.sliding_speed": [5, 8]},
        }
    )
    assert z.pad_count == 2 and z.scene(1).sliding_speed == pytest.approx(8.0)
    bad = [
        ({"parameters": {"friction.X": [1.0]}}, "unknown sweep parameter"),
        (
            {"sweep": {"base": "hf1", "mode": "zip"}, "parameters": {"friction.M": [0.5], "load.normal_force": [1, 2]}},
            "equal length",
        ),
        ({"sweep": {"base": "nope"}}, "neither a preset"),
        ({"parameters": {"patches.seed": [1.5]}}, "integers"),
        ({"parameters": {"friction.M": [-1.0]}}, "friction.M must be >= 0"),
        ({"extra": {}}, "unknown table"),
        ({"sweep": {"base": "hf1"}, "run": {"duration": 1e-6, "sample_dt": 1e-5}}, r"\(run\.sample_dt\) exceeds"),
    ]
    for doc, msg in bad:
        with pytest.raises(SweepError, match=msg):
            load_spec(doc)


def test_the_precision_follows_the_integrator_and_is_written_out() -> None:
    """A spec without ``precision`` runs ``strang`` in fp32 and the other integrators in fp64 (their defaults), and
    its hash holds the precision resolved: the same spec with ``precision = "fp64"`` written, or given as an override
    (``--precision fp64``), is one sweep, a sweep begun in fp64 from a spec without it continues that way."""
    doc = json.loads(json.dumps(TINY))
    doc["run"].pop("precision", None)
    assert load_spec(doc).precision == "fp32"
    adaptive = json.loads(json.dumps(doc))
    adaptive["run"]["integrator"] = "adaptive"
    assert load_spec(adaptive).precision == "fp64"
    written = json.loads(json.dumps(doc))
    written["run"]["precision"] = "fp64"
    assert load_spec(doc, precision="fp64").hash == load_spec(written).hash != load_spec(doc).hash
    # the doc the workers resolve again holds the settings resolved here: the same spec whatever their defaults
    resolved = load_spec(doc).doc["run"]
    assert resolved["precision"] == "fp32" and resolved["dt"] == 5e-8
    assert load_spec(load_spec(doc).doc).hash == load_spec(doc).hash


def test_a_sweep_begun_with_other_run_settings_is_refused_with_how_to_continue_it(tmp_path: Path) -> None:
    """A folder whose sweep ran in fp64 from the same spec: the spec without ``precision`` (fp32 for strang) is
    refused, naming the setting that differs and the option that continues it; with that option it continues."""
    from aca_warp.sweep.manifest import prepare_dir

    doc = json.loads(json.dumps(TINY))
    doc["run"].pop("precision", None)
    prepare_dir(load_spec(doc, precision="fp64"), tmp_path / "sw")
    with pytest.raises(SweepError, match=r"precision fp64 there, fp32 here\) \(to continue it: --precision fp64\)"):
        prepare_dir(load_spec(doc), tmp_path / "sw")
    assert prepare_dir(load_spec(doc, precision="fp64"), tmp_path / "sw")["shards"]


def test_a_sweep_continued_without_its_overrides_is_told_them(tmp_path: Path) -> None:
    """A sweep begun with --duration, --dt and --shard-size and run again without them ("run the same command
    again", the overrides forgotten): the refusal names each option with its value, the shard size too, and so it
    does where only the shard size differs; with them the sweep continues."""
    from aca_warp.sweep.manifest import prepare_dir

    doc = json.loads(json.dumps(TINY))
    prepare_dir(load_spec(doc, duration=2e-5, dt=1e-8, shard_size=1), tmp_path / "sw")
    with pytest.raises(SweepError) as e:
        prepare_dir(load_spec(doc), tmp_path / "sw")
    assert "(to continue it: --dt 1e-08 --duration 2e-05 --shard-size 1); its shard size (1 there, 3 here) differs" in (
        str(e.value)
    ), e.value
    with pytest.raises(
        SweepError, match=r"its shard size \(1 there, 3 here\) differs \(to continue it: --shard-size 1\)"
    ):
        prepare_dir(load_spec(doc, duration=2e-5, dt=1e-8), tmp_path / "sw")
    assert prepare_dir(load_spec(doc, duration=2e-5, dt=1e-8, shard_size=1), tmp_path / "sw")["shards"]


def test_a_refusal_offers_the_options_only_where_the_run_settings_alone_differ(tmp_path: Path) -> None:
    """Another sweep in the folder: where its parameters differ too the refusal says so and offers no options (they
    would meet a second refusal); where the spec is the same but its base scene file changed, it says that."""
    from aca_warp.sweep.manifest import prepare_dir

    doc = json.loads(json.dumps(TINY))
    doc["run"].pop("precision", None)
    prepare_dir(load_spec(doc, precision="fp64"), tmp_path / "sw")
    other = json.loads(json.dumps(doc))
    first = next(iter(other["parameters"]))
    other["parameters"][first] = list(other["parameters"][first])[:1]
    with pytest.raises(
        SweepError, match=r"fp32 here\); its parameters, pad count \(12 there, 6 here\) differ too"
    ) as e:
        prepare_dir(load_spec(other), tmp_path / "sw")
    assert "to continue it" not in str(e.value)
    base = tmp_path / "base.toml"
    base.write_text('[scene]\nname = "b"\n[patches]\ncount = 20\n')
    mine = {"sweep": {"name": "f", "base": "base.toml"}, "run": {"duration": 2e-6}, "parameters": {"friction.M": [0.6]}}
    prepare_dir(load_spec(mine, base_dir=tmp_path), tmp_path / "f")
    base.write_text(base.read_text().replace("20", "21"))
    with pytest.raises(SweepError, match="the spec is the same, so its base scene file base.toml"):
        prepare_dir(load_spec(mine, base_dir=tmp_path), tmp_path / "f")


def test_spec_check_builds_one_pad_per_value_but_not_per_seed(monkeypatch) -> None:
    """The spec's check builds the first and last pad and one pad per value of each parameter, but not one per seed
    (a sweep over many patch seeds would make every layout before it starts); a count that does not fit still fails
    at load time, naming its pad."""
    import aca_warp.sweep.spec as S

    built: list[dict] = []
    real = S.apply_parameters

    def counting(base, base_doc, values, **kw):
        if "patches.seed" in values:  # a pad (the default step's test of one value at a time has no seed)
            built.append(dict(values))
        return real(base, base_doc, values, **kw)

    monkeypatch.setattr(S, "apply_parameters", counting)
    load_spec({"sweep": {"base": "hf1"}, "parameters": {"patches.count": [30], "patches.seed": {"range": [1, 41]}}})
    assert sorted(v["patches.seed"] for v in built) == [1, 40]
    built.clear()
    load_spec({"sweep": {"base": "hf1"}, "parameters": {"patches.count": [20, 30, 40], "patches.seed": [1, 2, 3]}})
    assert sorted({v["patches.count"] for v in built}) == [20, 30, 40] and len(built) <= 4
    with pytest.raises(SweepError, match=r"pad \d+ .*patches.count"):
        load_spec({"sweep": {"base": "hf1"}, "parameters": {"patches.count": [20, 10**6], "patches.seed": [1, 2]}})


def test_pad_equals_hand_built_scene() -> None:
    """Pad 9 of the sweep (M 0.8, 400 N, seed 2) reproduces a scene built by hand, run alone."""
    s = _spec()
    base = preset("hf1")
    hand = base.replace(
        friction=Friction(M=0.8, mu_pad=base.friction.mu_pad),
        normal_force=400.0,
        patches=PatchGenerator(**{**base.origin["patches"], "count": 25, "seed": 2}).generate(base.pad),
        record=s.base.record,
    )
    m = build_model([hand], precision="fp32")
    res = run_hf(m, initial_state(m), RunOptions(duration=4e-6, integrator="strang"), record=hand.record)
    mb = build_model(s.scenes(range(9, 12)), precision="fp32")
    rb = run_hf(mb, initial_state(mb), RunOptions(duration=4e-6, integrator="strang"), record=hand.record)
    np.testing.assert_allclose(rb.collect().globals[:, 0], res.collect().globals[:, 0], rtol=1e-6, atol=0)


def test_the_crossing_treatment_is_a_run_setting(tmp_path: Path) -> None:
    """``run.crossing = "mean"`` (``--crossing mean``) enters the hash, the shards' run settings and the pads' run
    options; the default leaves the hashes of earlier sweeps as they were; another integrator is refused with the
    key named."""
    doc = json.loads(json.dumps(TINY))
    plain = load_spec(doc)
    assert "crossing" not in plain.run_settings() and run_options(plain).crossing == "point"
    mean = load_spec(doc, crossing="mean")
    assert mean.crossing == "mean" and mean.hash != plain.hash and run_options(mean).crossing == "mean"
    written = json.loads(json.dumps(doc))
    written["run"]["crossing"] = "mean"
    assert load_spec(written).hash == mean.hash
    bad = json.loads(json.dumps(written))
    bad["run"]["integrator"] = "adaptive"
    with pytest.raises(SweepError, match="run.crossing"):
        load_spec(bad)
    run_sweep(mean, tmp_path / "out", workers=0)
    with h5py.File(tmp_path / "out" / "shard-00000.h5") as f:
        assert json.loads(f.attrs["run"])["crossing"] == "mean"


@pytest.mark.parametrize(("integrator", "engine"), [("implicit-friction", "general"), ("adaptive", "onchip")])
def test_shard_files_name_the_engine(tmp_path: Path, integrator: str, engine: str) -> None:
    """A shard file's ``engine`` attribute is the engine that ran it (``auto`` runs ``implicit-friction`` on the
    general engine and ``adaptive`` on chip)."""
    spec = _spec(run__integrator=integrator)
    run_sweep(spec, tmp_path / "out", workers=0)
    with h5py.File(tmp_path / "out" / "shard-00000.h5") as f:
        assert f.attrs["engine"] == engine and f.attrs["integrator"] == integrator


def _listening_sockets() -> list[tuple[int, str, int]]:
    """(pid, address, port) of every listening inet socket of this process and its descendants."""
    me = psutil.Process()
    out = []
    for p in [me, *me.children(recursive=True)]:
        try:
            conns = p.net_connections(kind="inet")
        except psutil.NoSuchProcess:
            continue
        out += [(p.pid, c.laddr.ip, c.laddr.port) for c in conns if c.status == psutil.CONN_LISTEN]
    return out


def test_dask_equals_serial_and_resume(tmp_path: Path) -> None:
    spec = _spec()
    serial, dask_dir = tmp_path / "serial", tmp_path / "dask"
    r = run_sweep(spec, serial, workers=0)
    assert r.ran == [0, 1, 2, 3] and not r.failed and not r.faults
    ref = _outputs(serial)
    assert ref["mu"].shape == (12, 5) and np.all(np.isfinite(ref["mu"]))
    with h5py.File(serial / "shard-00001.h5", "r") as f:
        assert f.attrs["complete"] and f.attrs["spec_hash"] == spec.hash
        assert f["global/mu"].attrs["unit"] == "1" and f["parameters/load.normal_force"].attrs["unit"] == "N"
        assert list(f["pads/index"][()]) == [3, 4, 5]

    listening: list[tuple[int, str, int]] = []

    def log(line: str) -> None:  # called while the cluster runs: note every socket its processes listen on
        if line.startswith("running"):
            listening.extend(_listening_sockets())

    r = run_sweep(spec, dask_dir, workers=2, log=log)  # a local Dask cluster: two single-threaded worker processes
    assert r.workers == 2 and sorted(r.ran) == [0, 1, 2, 3] and not r.failed
    # this process (scheduler and the two nannies) and the two worker processes listen, on loopback only
    assert len({pid for pid, _, _ in listening}) >= 3, listening
    assert all(ipaddress.ip_address(ip).is_loopback for _, ip, _ in listening), listening
    _assert_same(_outputs(dask_dir), ref)

    # what a kill leaves behind: shard 1 mid-write (.partial, manifest 'queued'); shard 2's file lost although the
    # manifest says done; shard 3 written by a worker whose client died before recording it (manifest 'queued')
    man = json.loads((dask_dir / "manifest.json").read_text())
    os.replace(dask_dir / "shard-00001.h5", dask_dir / "shard-00001.h5.partial")
    (dask_dir / "shard-00002.h5").unlink()
    man["shards"][1]["state"] = man["shards"][3]["state"] = "queued"
    (dask_dir / "manifest.json").write_text(json.dumps(man))
    kept = {i: (dask_dir / f"shard-0000{i}.h5").stat().st_mtime_ns for i in (0, 3)}
    r = run_sweep(spec, dask_dir, workers=0)
    assert sorted(r.ran) == [1, 2] and sorted(r.skipped) == [0, 3]
    assert {i: (dask_dir / f"shard-0000{i}.h5").stat().st_mtime_ns for i in (0, 3)} == kept
    assert not list(dask_dir.glob("*.partial"))
    assert [s["state"] for s in json.loads((dask_dir / "manifest.json").read_text())["shards"]] == ["done"] * 4
    _assert_same(_outputs(dask_dir), ref)
    r = run_sweep(spec, dask_dir, workers=0)
    assert r.ran == [] and sorted(r.skipped) == [0, 1, 2, 3]

    other = _spec(run__duration=3e-6)
    with pytest.raises(SweepError, match="different sweep"):
        run_sweep(other, dask_dir, workers=0)
    r = run_sweep(other, dask_dir, workers=0, overwrite=True)
    assert sorted(r.ran) == [0, 1, 2, 3] and load_sweep(dask_dir)["mu"].shape == (12, 4)


def test_cli(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    spec = tmp_path / "s.toml"
    spec.write_text(
        '[sweep]\nbase = "hf1"\nshard_size = 2\n[run]\nduration = 2e-6\nprecision = "fp32"\n'
        '[base.patches]\ncount = 12\n[parameters]\n"friction.M" = [0.7, 0.8, 0.9]\n'
    )
    out = tmp_path / "o"
    assert main(["sweep", str(spec), "-o", str(out), "--workers", "0", "--quiet"]) == 0
    assert "2 shard(s) run, 0 skipped" in capsys.readouterr().out
    assert main(["sweep", str(spec), "-o", str(out), "--workers", "0", "--quiet"]) == 0
    assert "0 shard(s) run, 2 skipped" in capsys.readouterr().out
    assert main(["sweep", str(spec), "-o", str(out), "--workers", "0", "--shard-size", "3"]) == 2
    assert "pass --overwrite" in capsys.readouterr().err
    assert main(["sweep", str(tmp_path / "missing.toml"), "-o", str(out)]) == 2


@pytest.mark.parametrize(
    ("address", "message"),
    [
        ("tcp://127.0.0.1:1", "nothing listens at tcp://127.0.0.1:1 (connection refused)"),
        ("silent", "no Dask scheduler answered at tcp://127.0.0.1:{port} within 0.5 s"),
        ("notanaddress", "--scheduler 'notanaddress' is not a Dask scheduler address"),
    ],
)
def test_scheduler_that_does_not_answer(tmp_path: Path, capsys, monkeypatch, address: str, message: str) -> None:
    """A scheduler address Dask cannot parse, a port where nothing listens (refused: said at once, not after the
    connect timeout), or one whose listener never answers Dask's handshake within the timeout (a socket on loopback
    that accepts nothing): one line, exit 2, and nothing written (no sweep folder, no manifest)."""
    import socket

    from aca_warp.sweep import cluster

    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 0.5 if address != "tcp://127.0.0.1:1" else 600.0)
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nbase = "hf1"\n[run]\nduration = 2e-6\n[base.patches]\ncount = 12\n')
    out = tmp_path / "o"
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        port = silent.getsockname()[1]
        if address == "silent":
            address = f"tcp://127.0.0.1:{port}"
        assert main(["sweep", str(spec), "-o", str(out), "--scheduler", address, "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aca-warp: error: ") and message.format(port=port) in err[0], err
    assert not out.exists()


@pytest.mark.parametrize(
    ("lines", "said", "not_said"),
    [
        ('[run]\nduration = 2e-6\n[parameters]\n"disc.sliding_speed" = [36.0, 3600.0]\n',
         "set allow_implausible = true in the spec's [base.scene] table", "--allow-implausible"),
        ('[run]\nduration = 2e-5\nsample_dt = 1e-8\ndt = 1e-7\n[parameters]\n"friction.M" = [0.6]\n',
         "(run.sample_dt, seconds)", "--sample-dt"),
    ],
)  # fmt: skip
def test_a_sweeps_refusals_name_what_the_spec_takes(tmp_path: Path, capsys, lines: str, said: str, not_said: str):
    """A scene's refusal inside a sweep names the spec's key ([base.scene] allow_implausible, run.sample_dt), not the
    flags of aca-warp hf that aca-warp sweep does not take, from the command line and from the Python API alike."""
    from aca_warp.cli import main
    from aca_warp.common.errors import AcaError

    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nbase = "hf1"\n' + lines)
    assert main(["sweep", str(spec), "-o", str(tmp_path / "o"), "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert said in err and not_said not in err and not (tmp_path / "o").exists()
    with pytest.raises(AcaError) as e:
        load_spec(spec)
    assert said in str(e.value) and not_said not in str(e.value)


def test_an_interrupt_after_every_shard_finished_says_the_sweep_is_complete(tmp_path: Path) -> None:
    """The interrupt line of a sweep whose shards had all finished (the signal came as it closed) says it is complete,
    not that running it again finishes it; with shards left, it says how many finished and what to do."""
    from aca_warp.sweep import run_sweep
    from aca_warp.sweep.commands import _interrupted_line
    from aca_warp.sweep.manifest import MANIFEST

    assert not run_sweep(load_spec(TINY), tmp_path / "o", workers=0).failed
    line = _interrupted_line(str(tmp_path / "o"), KeyboardInterrupt())
    assert (
        "after every shard had finished" in line and "the sweep is complete" in line and "again to finish" not in line
    )
    manifest = tmp_path / "o" / MANIFEST
    m = json.loads(manifest.read_text())
    m["shards"][-1]["state"] = "interrupted"
    manifest.write_text(json.dumps(m))
    line = _interrupted_line(str(tmp_path / "o"), KeyboardInterrupt())
    last = len(m["shards"]) - 1
    assert f"shard(s) {last} marked interrupted" in line and "run the same command again to finish the sweep" in line


@pytest.mark.parametrize(
    ("text", "said"),
    [
        ("", "is empty: it would run one pad of the default scene"),
        ('[sweep]\nbase = "nothere.toml"\n', "'nothere.toml': no such file in"),
        ('[sweep]\nbase = "hf1"\n[parameters]\n"pad.r_inner" = [100.0]\n', "did you mean mm? (100 mm = 0.1 m)"),
        ('[sweep]\nbase = "hf1"\n[run]\ntolerance = 1e-9\n', "strang takes none: leave it out"),
        ('[sweep]\nbase = "hf1"\n[parameters]\n"patches.area_min" = [20.0]\n', "did you mean mm² or µm²?"),
    ],
)  # fmt: skip
def test_a_spec_that_would_do_other_than_it_says_is_refused(tmp_path: Path, text: str, said: str) -> None:
    """An empty spec (it would run the default scene), a base file that is not there, a pad radius typed in mm (said
    so before the radii are compared): one line each."""
    spec = tmp_path / "s.toml"
    spec.write_text(text)
    with pytest.raises(SweepError, match=re.escape(said)):
        load_spec(spec)


@pytest.mark.parametrize(
    ("table", "typed", "meant"),
    [
        ("sweep", "shard_sise", "shard_size"),
        ("run", "duraton", "duration"),
        ("parameters", '"friction.m"', "friction.M"),
    ],
)
def test_a_mistyped_spec_key_names_the_nearest(tmp_path: Path, table: str, typed: str, meant: str) -> None:
    """A mistyped key of [sweep], [run] or [parameters] is refused naming the nearest allowed one."""
    spec = tmp_path / "s.toml"
    value = "[0.5]" if table == "parameters" else "4"
    head = '[sweep]\nbase = "hf1"\n' + ("" if table == "sweep" else f"[{table}]\n")
    spec.write_text(head + f"{typed} = {value}\n")
    with pytest.raises(SweepError, match=re.escape(f"(did you mean {meant!r}?)")):
        load_spec(spec)


def test_a_missing_spec_named_like_the_shipped_example_points_to_it(tmp_path: Path) -> None:
    """The help's example path read from another folder: the refusal names where the installed example is."""
    from importlib import resources

    shipped = resources.files("aca_warp.data") / "sweep_hf1.toml"
    with pytest.raises(SweepError, match=re.escape(f"the example of that name shipped with aca_warp is {shipped}")):
        load_spec(tmp_path / "aca_warp" / "data" / "sweep_hf1.toml")
    with pytest.raises(SweepError) as e:
        load_spec(tmp_path / "mine.toml")
    assert "shipped" not in str(e.value)


def test_the_first_line_says_the_run_the_shards_take(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The sweep's first line gives the step the shards take and the time they cover: a step fitted to the sample
    interval and a duration that is no whole number of them are said with what was asked; one pad is "1 pad"."""
    from aca_warp.cli import main

    doc = small_sweep_doc("one", count=12, duration=1e-5, parameters={"friction.M": [0.6]})
    doc["run"]["sample_dt"] = 3e-6
    spec = tmp_path / "s.toml"
    spec.write_text(toml_text(doc))
    capsys.readouterr()
    assert main(["sweep", str(spec), "-o", str(tmp_path / "o"), "--workers", "0", "--dt", "4e-7"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert (
        "1 pad (friction.M), 1 shard(s) of up to 1 pad, 9e-06 s each (1e-05 s asked: whole sample intervals of "
        in first
    )
    assert "3e-06 s), strang fp32 at 3.75e-07 s (4e-07 s asked, fitted to the 3e-06 s samples)" in first, first
    assert load_sweep(tmp_path / "o")["time"][-1] == pytest.approx(9e-6)


def test_an_unfinished_sweep_reads_as_what_it_holds_and_says_so(tmp_path: Path) -> None:
    """load_sweep of a sweep whose shard 1 has not run: its finished pads, row k the pad ``pad_index[k]``,
    ``complete`` False and a warning naming the shard and the count; finished, ``complete`` and no warning; every
    output's, the time's and every parameter's unit."""
    import warnings

    out = tmp_path / "sw"
    run_sweep(_spec(), out, workers=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        whole = load_sweep(out)
    assert whole["complete"] and whole["units"]["mu"] == "1" and whole["units"]["time"] == "s"
    assert whole["units"]["load.normal_force"] == "N" and whole["units"]["torque"] == "N m"
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["shards"][1]["state"] = "pending"
    (out / "manifest.json").write_text(json.dumps(manifest))
    with pytest.warns(UserWarning, match=r"holds 9 of its 12 pads: shard\(s\) 1 not finished"):
        part = load_sweep(out)
    assert not part["complete"] and list(part["pad_index"]) == [0, 1, 2, 6, 7, 8, 9, 10, 11]
    assert np.array_equal(part["mu"], whole["mu"][part["pad_index"]])


def test_a_sweep_its_folder_has_no_room_for_is_refused_before_its_shards(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Where the folder's free space is less than the shard files to write (the estimate of shard_bytes, which a
    written shard does not exceed), the sweep is refused, exit 4, before any shard is written (its manifest says them
    pending); a sweep whose shards are all written needs no room, with --overwrite too (its own shards are kept)."""
    import os

    from aca_warp.common import files
    from aca_warp.common.errors import StorageError
    from aca_warp.sweep.shard import shard_bytes

    out = tmp_path / "sw"
    spec = _spec()
    need = shard_bytes(spec, list(range(spec.shard_count)))
    real = os.statvfs

    class Full:  # 4 KiB free
        f_bavail, f_frsize, f_blocks = 1, 4096, 10

    monkeypatch.setattr(files.os, "statvfs", lambda p: Full())
    with pytest.raises(
        StorageError, match=r"the 4 shard file\(s\) to write will take about .* has 0.004096 MB free; no "
    ) as e:
        run_sweep(spec, out, workers=0)
    assert e.value.exit_code == 4 and need > 4096 and not list(out.glob("shard-*"))
    assert {s["state"] for s in json.loads((out / "manifest.json").read_text())["shards"]} == {"pending"}
    monkeypatch.setattr(files.os, "statvfs", real)
    run_sweep(spec, out, workers=0)
    assert all((out / f"shard-{i:05d}.h5").stat().st_size <= shard_bytes(spec, [i]) for i in range(spec.shard_count))
    monkeypatch.setattr(files.os, "statvfs", lambda p: Full())
    assert run_sweep(spec, out, workers=0).skipped == [0, 1, 2, 3]
    assert run_sweep(spec, out, workers=0, overwrite=True).skipped == [0, 1, 2, 3]


def test_a_sweep_whose_manifest_was_lost_continues_from_its_shards(tmp_path: Path) -> None:
    """A folder whose manifest is gone: the same spec continues from its finished shards (verified, not run again;
    the manifest made anew), with a pad taken out of a shard beside them; shards of another spec, or an unfinished
    one, are still refused."""
    import shutil

    out = tmp_path / "sw"
    run_sweep(_spec(), out, workers=0)
    (out / "manifest.json").unlink()
    shutil.copy(out / "shard-00000.h5", out / "shard-00000_pad1.h5")  # as analyze --pad names what it takes out
    again = run_sweep(_spec(), out, workers=0)
    assert again.ran == [] and again.skipped == [0, 1, 2, 3]
    assert [s["state"] for s in json.loads((out / "manifest.json").read_text())["shards"]] == ["done"] * 4
    (out / "manifest.json").unlink()
    with pytest.raises(SweepError, match="5 shard file.s. without a manifest"):  # (the pad file counted)
        run_sweep(_spec(run__duration=8e-6), out, workers=0)
    (out / "shard-00002.h5").rename(out / "shard-00002.h5.partial")
    with pytest.raises(SweepError, match="without a manifest"):
        run_sweep(_spec(), out, workers=0)


def test_wrong_folders_are_named_for_what_they_are(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """A folder given as the spec, an output under /proc (a folder that takes no file), a sweep folder that does
    not exist and a finished shard's file gone: each one line that says which (not "not found", "does not exist" or
    "remove it")."""
    from aca_warp.cli import main

    spec = tmp_path / "s.toml"
    spec.write_text(toml_text(TINY))
    for argv, said in (
        ([str(tmp_path), "-o", str(tmp_path / "o")], f"sweep spec {tmp_path} is a folder, not a TOML spec file"),
        ([str(spec), "-o", "/proc/aca-warp-sweep"], "output folder /proc takes no new file (a virtual file system)"),
    ):
        capsys.readouterr()
        assert main(["sweep", *argv, "--workers", "0", "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [f"aca-warp: error: {said}"], err
    with pytest.raises(SweepError, match="sweep directory .*nothere does not exist"):
        load_sweep(tmp_path / "nothere")
    run_sweep(_spec(), tmp_path / "sw", workers=0)
    (tmp_path / "sw" / "shard-00001.h5").unlink()
    with pytest.raises(SweepError, match=r"shard-00001.h5 is missing \(its manifest has it finished\): run the sweep"):
        load_sweep(tmp_path / "sw")
    assert run_sweep(_spec(), tmp_path / "sw", workers=0).ran == [1]


def test_an_empty_output_folder_is_refused_not_taken_for_the_current_one(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``sweep -o ''`` (an unset variable in a script) and ``run_sweep(spec, '')``: one line, exit 2, nothing
    written into the current folder (``Path('')`` is it); ``-o .`` still names it."""
    from aca_warp.cli import main

    monkeypatch.chdir(tmp_path)
    spec = tmp_path / "s.toml"
    spec.write_text(toml_text(TINY))
    capsys.readouterr()
    assert main(["sweep", str(spec), "-o", "", "--workers", "0", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["aca-warp: error: output folder '' names no folder; give one (. for the current folder)"], err
    with pytest.raises(SweepError, match="names no folder"):
        run_sweep(_spec(), "", workers=0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_a_base_that_records_per_patch_histories_is_refused_where_the_sweep_starts(tmp_path: Path) -> None:
    """A shard holds no per-patch histories: a sweep whose base records them is refused before anything is written
    (the spec itself loads: shards written before the check still give their pads)."""
    doc = json.loads(json.dumps(TINY))
    doc.setdefault("base", {})["record"] = {"patches": ["velocity"]}
    spec = load_spec(doc)
    with pytest.raises(SweepError, match="which a sweep's shards do not hold"):
        run_sweep(spec, tmp_path / "o", workers=0)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("step", "said"),
    [
        ("1.2e-6", "pad 0 ({'load.normal_force': 300.0, 'friction.M': 0.6}): dt = 1.2e-06 s exceeds"),  # every pad
        ("1.2e-8", "pad 3 ({'load.normal_force': 3000.0, 'friction.M': 0.7}): dt = 1.2e-08 s exceeds"),  # a corner
    ],
)
def test_a_step_a_pad_cannot_take_is_refused_where_the_sweep_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture, step: str, said: str
) -> None:
    """A fixed step beyond a pad's stable-step estimate is one line (exit 2) naming the pad and the spec's key for
    the step, before the sweep's folder exists, instead of every shard failing at run time: a step too large for
    every pad, and one too large only where both swept parameters are at the top of their ranges (symplectic Euler
    at 1.2e-8 s, whose friction bound is 1.19e-8 s at 3000 N and M = 0.7, 1.39e-8 s at M = 0.6: a corner of the
    product, which neither parameter's own extreme reaches)."""
    from aca_warp.cli import main

    doc = small_sweep_doc(
        "stiff",
        count=12,
        duration=1e-5,
        parameters={"load.normal_force": [300.0, 3000.0, 400.0], "friction.M": [0.6, 0.7]},
    )
    doc["run"] |= {"integrator": "symplectic-euler", "sample_dt": 1.2e-6}
    spec = tmp_path / "s.toml"
    spec.write_text(toml_text(doc))
    capsys.readouterr()
    assert main(["sweep", str(spec), "-o", str(tmp_path / "o"), "--workers", "0", "--dt", step, "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and said in err[0] and "smaller run.dt" in err[0] and "--force" not in err[0], err
    assert not (tmp_path / "o").exists()


def test_a_pad_the_start_check_does_not_reach_fails_its_shard_in_the_spec_s_words(tmp_path: Path) -> None:
    """A zip sweep whose middle pad (2000 N, M = 0.7: stable step 1.34e-8 s) is stiffer than its ends (the checked
    pads): its shard fails at run time, and the reason names the spec's key for the step and no option a sweep has
    not (--force); the other shards run."""
    doc = small_sweep_doc(
        "z",
        count=12,
        duration=1e-5,
        parameters={"load.normal_force": [300.0, 2000.0, 3000.0], "friction.M": [0.7, 0.7, 0.6]},
    )
    doc["sweep"] |= {"mode": "zip", "shard_size": 1}
    doc["run"] |= {"integrator": "symplectic-euler", "sample_dt": 1.2e-6, "dt": 1.36e-8}
    res = run_sweep(load_spec(doc), tmp_path / "o", workers=0)
    assert res.ran == [0, 2] and list(res.failed) == [1], res.failed
    assert (
        "choose a smaller run.dt or an implicit-friction integrator" in res.failed[1]
        and "--force" not in res.failed[1]
        and "force=True" not in res.failed[1]
    )


def test_the_pads_whose_runs_are_checked_where_a_sweep_starts() -> None:
    """check_pads: the first and last pad, each parameter's smallest and largest value, the corners of up to
    four parameters' ranges (else the pads where all are smallest or all largest); the seeds and text values are
    not ranges."""
    from aca_warp.sweep.prepare import check_pads

    def pads(parameters: dict, mode: str = "product") -> list[int]:
        doc = small_sweep_doc("c", count=12, duration=1e-6, parameters=parameters)
        doc["sweep"]["mode"] = mode
        return check_pads(load_spec(doc))

    # 3 x 3 product (F_N outer): corners (300, 0.6) 0, (300, 0.8) 2, (500, 0.6) 6, (500, 0.8) 8
    two = {"load.normal_force": [300.0, 400.0, 500.0], "friction.M": [0.6, 0.7, 0.8]}
    assert pads(two) == [0, 2, 6, 8]
    assert pads(two | {"patches.seed": {"range": [1, 3]}}) == [0, 4, 12, 16, 17]  # two seeds innermost: the first
    assert pads({"load.normal_force": [400.0, 300.0, 500.0, 450.0]}) == [0, 1, 2, 3]
    assert pads({"load.normal_force": [400.0, 300.0, 500.0], "friction.M": [0.7, 0.8, 0.6]}, "zip") == [0, 1, 2]
    five = {
        "friction.M": [0.6, 0.8],
        "friction.mu_pad": [0.3, 0.4],
        "load.normal_force": [300.0, 400.0],
        "friction.slope": [200.0, 300.0],
        "disc.sliding_speed": [9.0, 10.0],
    }
    got = pads(five)  # 32 pads: each parameter's ends are pads 0 and one with only it raised, and the last
    assert got == sorted({0, 31, 16, 8, 4, 2, 1}), got
    text = {"initial.state": ["equilibrium", "rest"]} | {k: two[k][::2] for k in two}  # 2 x 2 x 2, text outermost
    assert pads(text) == [0, 1, 2, 3, 7]  # the numeric corners with the first text value, and the last pad


@pytest.mark.parametrize("parameter", [{"range": [20, 20]}, {"range": [5, 1]}, []])
def test_an_empty_parameter_says_why_where_it_was_a_range(parameter: object) -> None:
    """A parameter with no values: a range is explained (it stops before its stop; counting down needs a negative
    step), an empty list is not."""
    doc = json.loads(json.dumps(TINY))
    doc["parameters"]["patches.seed"] = parameter
    with pytest.raises(SweepError) as e:
        load_spec(doc)
    assert "has no values" in str(e.value)
    assert ("counting down needs a negative step" in str(e.value)) == isinstance(parameter, dict)


def _file_sweep(folder: Path, patches) -> tuple[dict, Path]:
    """A sweep of four pads in two shards over the patches of ``folder/p.h5`` (written from ``patches``)."""
    from aca_warp.scene import write_patch_file

    write_patch_file(folder / "p.h5", patches)
    (folder / "b.toml").write_text('[scene]\nname = "b"\n[patches]\nfile = "p.h5"\n')
    doc = {
        "sweep": {"name": "f", "base": "b.toml", "shard_size": 2},
        "run": {"duration": 8e-6, "precision": "fp32"},
        "parameters": {"friction.M": [0.6, 0.7, 0.8, 0.9]},
    }
    return doc, folder / "out"


def test_a_patch_file_rewritten_under_its_name_is_caught_by_resume_and_pad(tmp_path: Path, capsys) -> None:
    """A base whose patches come from a file: the spec names the file by its path (its hash does not change with
    the file), so the folder and shards record the patches' digest; a sweep continued, or a pad taken out, after the
    file was rewritten with other patches of the same count is refused, and goes on once the file is restored. A
    folder of a sweep begun before the digest was recorded continues as before."""
    from aca_warp.scene import Patches, write_patch_file

    src = PatchGenerator(count=20, seed=3).generate(preset("hf1").pad)
    doc, out = _file_sweep(tmp_path, src)
    spec = load_spec(doc, base_dir=tmp_path)
    assert spec.patch_data is not None and load_spec(TINY, base_dir=tmp_path).patch_data is None
    assert not run_sweep(spec, out, workers=0).failed
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["patch_data"] == spec.patch_data
    assert all("patch_data" not in s for s in manifest["shards"])  # once, at the top
    with h5py.File(out / "shard-00000.h5", "r") as f:
        assert f.attrs["patch_data"] == spec.patch_data
    moved = Patches(src.x + 1e-6, src.y, src.area, src.height)
    write_patch_file(tmp_path / "p.h5", moved)
    other = load_spec(doc, base_dir=tmp_path)
    assert other.hash == spec.hash and other.patch_data != spec.patch_data
    with pytest.raises(SweepError, match="begun over other patches: its patch file .*p.h5 has changed since"):
        run_sweep(other, out, workers=0)
    assert main(["analyze", str(out / "shard-00001.h5"), "--pad", "2", "--no-sync"]) == 2
    assert "ran over other patches than its patch file" in capsys.readouterr().err
    assert not list(out.glob("*pad*"))
    write_patch_file(tmp_path / "p.h5", src)
    r = run_sweep(load_spec(doc, base_dir=tmp_path), out, workers=0)
    assert r.ran == [] and r.skipped == [0, 1]
    assert main(["analyze", str(out / "shard-00001.h5"), "--pad", "2", "--no-sync"]) == 0
    # a folder begun before the digest was recorded: no record in the manifest nor in the shards, continued as before
    manifest = json.loads((out / "manifest.json").read_text())
    del manifest["patch_data"]
    (out / "manifest.json").write_text(json.dumps(manifest))
    for p in out.glob("shard-0000?.h5"):
        with h5py.File(p, "a") as f:
            del f.attrs["patch_data"]
    write_patch_file(tmp_path / "p.h5", moved)
    r = run_sweep(load_spec(doc, base_dir=tmp_path), out, workers=0)
    assert r.ran == [] and r.skipped == [0, 1]
    assert "patch_data" not in json.loads((out / "manifest.json").read_text())


def test_a_patch_file_rewritten_while_the_sweep_runs_fails_the_shards_made_over_it(tmp_path: Path) -> None:
    """The file rewritten between two shards of one call: the later shard, made over the new patches, is failed
    with the reason (not recorded as done), and runs again once the file is restored."""
    from aca_warp.scene import Patches, write_patch_file

    src = PatchGenerator(count=20, seed=3).generate(preset("hf1").pad)
    doc, out = _file_sweep(tmp_path, src)

    def rewrite(line: str) -> None:
        if line.startswith("shard 0:"):
            write_patch_file(tmp_path / "p.h5", Patches(src.x, src.y + 1e-6, src.area, src.height))

    r = run_sweep(load_spec(doc, base_dir=tmp_path), out, workers=0, overlap=False, prepare=0, log=rewrite)
    assert r.ran == [0] and list(r.failed) == [1]
    assert "ran over other patches than the sweep began with" in r.failed[1]
    states = [s["state"] for s in json.loads((out / "manifest.json").read_text())["shards"]]
    assert states == ["done", "failed"]
    assert not (out / "shard-00001.h5").exists()  # not the sweep's data: removed, nothing to take a pad out of
    write_patch_file(tmp_path / "p.h5", src)
    r = run_sweep(load_spec(doc, base_dir=tmp_path), out, workers=0, prepare=0)
    assert r.ran == [1] and not r.failed


def test_the_patch_digest_comes_with_shards_a_preparation_pool_made(tmp_path: Path) -> None:
    """A shard prepared in a pool process (its spec resolved there) records the same digest as the manifest."""
    src = PatchGenerator(count=20, seed=3).generate(preset("hf1").pad)
    doc, out = _file_sweep(tmp_path, src)
    spec = load_spec(doc, base_dir=tmp_path)
    assert not run_sweep(spec, out, workers=0, prepare=1).failed
    assert json.loads((out / "manifest.json").read_text())["patch_data"] == spec.patch_data
    for i in (0, 1):
        with h5py.File(out / f"shard-0000{i}.h5", "r") as f:
            assert f.attrs["patch_data"] == spec.patch_data


def _finished_tiny_sweep(tmp_path: Path) -> tuple[Path, list[str], dict[str, bytes]]:
    """TINY run to the end into ``tmp_path/o`` in this process: its folder, the command that ran it and its files."""
    spec = tmp_path / "s.toml"
    spec.write_text(toml_text(TINY))
    out = tmp_path / "o"
    args = ["sweep", str(spec), "-o", str(out), "--workers", "0"]
    assert main(args) == 0
    return out, args, {p.name: p.read_bytes() for p in out.iterdir()}


def test_a_finished_sweep_in_a_folder_that_takes_no_file_is_complete(tmp_path: Path, monkeypatch, capsys) -> None:
    """A finished sweep run again where its folder takes no new file (read only: neither the command's probe file nor
    the sweep's lock file can be made) says every shard is finished and exits 0, writing nothing; one asked to
    ``--overwrite``, one whose manifest records a shard otherwise than its file does (its client died before it
    recorded the shard: only a writable folder can record it), and an unfinished one are refused in one line
    (exit 4)."""
    from aca_warp.common import files
    from aca_warp.sweep.manifest import MANIFEST

    out, args, before = _finished_tiny_sweep(tmp_path)
    capsys.readouterr()

    def denied(*a, **kw):
        raise PermissionError(13, "Permission denied")

    with monkeypatch.context() as m:
        m.setattr(files, "_take", denied)
        m.setattr(files.tempfile, "mkstemp", denied)
        assert main(args) == 0
        said = capsys.readouterr()
        assert f"4 of 4 shard(s) already finished, skipped ({out} takes no new file)" in said.out, said
        assert "0 shard(s) run, 4 skipped" in said.out and said.err == ""
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before
        assert main([*args, "--overwrite"]) == 4
        assert "cannot write into" in capsys.readouterr().err
        manifest = json.loads((out / MANIFEST).read_text())
        stale = json.loads(json.dumps(manifest))
        stale["shards"][0]["state"] = "failed"
        (out / MANIFEST).write_text(json.dumps(stale))  # the manifest behind its shard file
        assert main(args) == 4
        (out / MANIFEST).write_text(json.dumps(manifest))
        (out / "shard-00003.h5").unlink()  # a shard file missing
        assert main(args) == 4
        errs = capsys.readouterr().err.split("aca-warp: error: ")
        assert errs[0] == "" and len(errs) == 3, errs
        for err in errs[1:]:
            assert err.startswith(f"cannot write into {out} (permission denied)") and err.count("\n") == 1, err


def test_a_finished_sweep_on_a_read_only_mount_is_complete(tmp_path: Path) -> None:
    """The same through a real read-only folder (a read-only bind mount, or a folder without write permission for
    another user than root): exit 0, nothing on stderr, nothing written."""
    from test_cli_faults import read_only

    out, args, before = _finished_tiny_sweep(tmp_path)
    results = read_only(out, [args])
    if results is None:
        pytest.skip("no way to make a folder read-only here (no user namespaces, and root ignores permissions)")
    assert results == [(0, "")], results
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
