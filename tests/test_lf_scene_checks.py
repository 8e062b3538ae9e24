"""What an LF scene is refused for when it is read (exit 2, one line, before anything runs): unit mistakes of every
``[lf]`` constant with a unit, snapshot times that would collide in the run file or never be taken, a schedule
without a loaded application on a sliding disc, seeds the random numbers cannot hold. Scene loading only, built on
the packaged preset ``multiscale``."""

from __future__ import annotations

import copy
import dataclasses
from importlib import resources
from pathlib import Path

import pytest
from procs import error_lines

from aca_warp.cli import main
from aca_warp.common.errors import SceneError, command_line
from aca_warp.common.plausible import RANGES
from aca_warp.lf.scene import (
    LF_KINDS,
    SEGMENT_KINDS,
    LFConstants,
    LFScene,
    Segment,
    lf_scene_from_dict,
    lf_scene_to_dict,
    load_lf_scene,
    step_table,
)
from aca_warp.scene import preset_document

PRESET = preset_document("multiscale")
# [lf] constants without a unit: counts, switches, fractions, probabilities (each bounded by its own check)
UNITLESS = ("seed", "capacity", "coulomb", "mu_coulomb", "contact_iterations", "contact_tol", "gamma_disc")
UNITLESS += ("kappa_d", "f_ret", "p_cap", "p_store", "p_remob", "p_birth", "compact_every")
# a 1.5 s schedule: one application, one pause
SHORT = [
    {"kind": "application", "duration": 1.0, "pressure_bar": 10.0, "sliding_speed": 10.0, "ramp": 0.2},
    {"kind": "pause", "duration": 0.5},
]


def preset(**tables: dict) -> dict:
    """The preset's document without initial patches (scene loading only), ``tables`` merged in (``schedule``:
    replaced)."""
    doc = copy.deepcopy(PRESET)
    doc["patches"] = {"count": 0}
    for table, values in tables.items():
        if table == "schedule":
            doc["schedule"] = values
        else:
            doc.setdefault(table, {}).update(values)
    return doc


def refused(doc: dict, *, allow_implausible: bool = False) -> str:
    with pytest.raises(SceneError) as e:
        lf_scene_from_dict(doc, allow_implausible=allow_implausible)
    return str(e.value)


# ----------------------------------------------------------------------------------------------- unit mistakes


@pytest.mark.parametrize(
    ("table", "key", "value", "message", "hint"),
    [
        ("lf", "T_amb", 20.0, "lf.T_amb = 20 K — below 150 K", "did you mean °C?"),
        ("lf", "T_c", 126.85, "lf.T_c = 126.85 K — below 150 K", "did you mean °C?"),  # 400 °C
        ("lf", "T_kill", 700, "lf.T_kill = 700 K", None),  # 700 °C is a valid 700 K: within the range
        ("lf", "cell", 1, "lf.cell = 1 m — beyond 0.02 m", "did you mean mm? (1 mm = 0.001 m)"),
        ("lf", "A_max", 4.0, "lf.A_max = 4 m² — beyond 0.001 m²", "did you mean mm²? (4 mm² = 4e-06 m²)"),
        ("lf", "A_min", 1e-14, "lf.A_min = 1e-14 m² — below 1e-12 m²", "did you convert mm² to m² twice"),
        ("lf", "cand_margin", 0.5, "lf.cand_margin = 0.5 m — beyond", "did you mean mm?"),
        ("lf", "d_d", 20, "lf.d_d = 20 m — beyond 0.1 m", "did you mean mm"),
        ("lf", "t_eff", 30, "lf.t_eff = 30 m — beyond", "µm = 3e-05 m"),
        ("lf", "L_b", 1.0, "lf.L_b = 1 m — beyond", "1 mm = 0.001 m"),
        ("lf", "t0", 3, "lf.t0 = 3 m — beyond", "3 µm = 3e-06 m"),
        ("lf", "s_max_thick", 3, "lf.s_max_thick = 3 m — beyond", "3 µm = 3e-06 m"),
        ("lf", "rho_d", 7.2, "lf.rho_d = 7.2 kg/m³ — below 100", "did you mean g/cm³?"),
        ("lf", "c_p", 1.0, "lf.c_p = 1 J/(kg K) — below 10", "did you mean kJ/(kg K)?"),
        ("lf", "k_d", 5e4, "lf.k_d = 50000 W/(m K) — beyond", "did you mean mW/(m K)?"),
        ("lf", "h_conv", 0.05, "lf.h_conv = 0.05 W/(m² K) — below 0.1", "did you mean kW/(m² K)?"),
        ("lf", "alpha_d", 12, "lf.alpha_d = 12 1/K — beyond", "did you mean µm/(m K)?"),
        ("lf", "wear_m", 2e-4, "lf.wear_m = 0.0002 m³/J — beyond", "did you mean mm³/(N m)?"),
        ("lf", "k_shrink", 1e-24, "lf.k_shrink = 1e-24 m³/J — below", "twice"),
        ("lf", "p_comp", 300, "lf.p_comp = 300 Pa — below 1000 Pa", "did you mean kPa or bar?"),
        ("lf", "newton_per_bar", 0.37, "lf.newton_per_bar = 0.37 N/bar — below 1", "did you mean kN/bar?"),
        ("lf", "lam0", 1e5, "lf.lam0 = 100000 1/s — beyond", "check the unit"),
        ("lf", "T_s", 1e5, "lf.T_s = 100000 K — beyond", "check the"),
        ("material", "matrix_stiffness", 185, "material.matrix_stiffness = 185 N/m³ — below", "N/mm³"),
        ("schedule", "ramp", 2e4, "schedule[0].ramp = 20000 s — beyond 10000 s", "did you mean ms?"),
    ],
)
def test_unit_mistakes_in_lf_tables_are_named(table, key, value, message, hint) -> None:
    """A value far outside a brake pad's range is refused with the range and the likely unit; allow_implausible
    (the argument or the scene key) lifts the check exactly as for the other keys."""
    if table == "schedule":  # a ramp in ms: refused before its ordering against the duration
        doc = preset(schedule=[{**SHORT[0], "duration": 1e4, key: value}])
        assert message in refused(doc) and hint in refused(doc)
        assert "must be shorter than the duration" in refused(doc, allow_implausible=True)
        return
    else:
        doc = preset(**{table: {key: value}})
    if hint is None:  # inside the range: loads
        assert getattr(lf_scene_from_dict(doc).lf, key) == value
        return
    err = refused(doc)
    assert message in err and hint in err and "allow_implausible=True" in err, err
    assert "\n" not in err
    allowed = lf_scene_from_dict(doc, allow_implausible=True)
    assert allowed.allow_implausible
    doc["scene"]["allow_implausible"] = True
    assert lf_scene_from_dict(doc).allow_implausible


def test_every_lf_constant_with_a_unit_is_bounded() -> None:
    """Each [lf] constant is either bounded by a plausible range or has no unit; the preset passes every range,
    and a value 1e7 times its default (1e6 for a default of 0) is refused naming the key, from a TOML document
    and from Python (LFScene with LFConstants)."""
    names = {f.name for f in dataclasses.fields(LFConstants)}
    assert set(LF_KINDS) | set(UNITLESS) == names and not set(LF_KINDS) & set(UNITLESS)
    assert set(LF_KINDS.values()) | set(SEGMENT_KINDS.values()) <= set(RANGES)
    base = lf_scene_from_dict(preset())
    for key in LF_KINDS:
        default = getattr(LFConstants(), key)
        big = default * 1e7 if default else 1e6
        err = refused(preset(lf={key: big}))
        assert err.startswith(f"lf.{key} = {big:g} ") and "— beyond" in err, err
    for key, value in (("T_amb", 20.0), ("cell", 1.0), ("A_max", 4.0)):
        lf = dataclasses.replace(base.lf, **{key: value})
        with pytest.raises(SceneError, match=f"lf.{key} = "):
            base.replace(lf=lf)
        assert getattr(base.replace(lf=lf, allow_implausible=True).lf, key) == value


def test_lf_unit_mistake_at_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """`aca-warp lf` with T_amb in °C: exit 2, one line naming --allow-implausible, nothing written."""
    s = tmp_path / "lf.toml"
    text = resources.files("aca_warp.data").joinpath("multiscale.toml").read_text()
    s.write_text(text.replace("[lf]\n", "[lf]\nT_amb = 20.0\n", 1))
    capsys.readouterr()
    assert main(["lf", str(s), "-o", str(tmp_path / "out.h5"), "--no-progress"]) == 2
    err = error_lines(capsys.readouterr().err)
    assert len(err) == 1 and "lf.T_amb = 20 K — below 150 K" in err[0] and "--allow-implausible" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lf.toml"]


# ----------------------------------------------------------------------------------------------- snapshots


@pytest.mark.parametrize(
    ("times", "message"),
    [
        ([0.5, 0.5], "snapshots.times lists 0.5 s twice"),
        ([0.25, 1.0, 0.25], "snapshots.times lists 0.25 s twice"),
        ([0.1234567, 0.1234568], "both name the snapshot t0.123457s"),
        ([-0.5], "snapshots.times must be > 0, got -0.5"),
        ([0.0], "snapshots.times must be > 0, got 0"),
        (["0.5"], "snapshots.times must be a number, got '0.5'"),
        ([[0.5]], "snapshots.times must be a number"),
        ([True], "snapshots.times must be a number, got True"),
        (0.5, "snapshots.times must be a list of seconds"),
    ],
)
def test_malformed_snapshot_times_are_refused(times, message) -> None:
    """Two snapshots of one name (the run file's /snapshots/NAME), a time that is not a positive number: refused
    when the scene is read."""
    err = refused(preset(schedule=SHORT, snapshots={"times": times}))
    assert message in err, err


def test_snapshot_times_within_the_schedule_in_any_order() -> None:
    """Times up to the schedule's last step, in any order, load and are taken in step order; a shorter run (the
    duration of step_table, `--duration`) still leaves out the later ones; the run file's copy reads back."""
    scene = lf_scene_from_dict(preset(schedule=SHORT, snapshots={"times": [1.5, 0.3, 1.0]}))
    assert scene.snapshot_times == (1.5, 0.3, 1.0)
    names = [n for n, _ in step_table(scene).snapshots]
    assert names == ["app1_start", "t0.3s", "app1_end", "t1s", "t1.5s"]
    assert [n for n, _ in step_table(scene, 0.5).snapshots] == ["app1_start", "t0.3s"]
    assert lf_scene_from_dict(lf_scene_to_dict(scene)).snapshot_times == scene.snapshot_times
    with pytest.raises(SceneError, match="lists 0.3 s twice"):
        scene.replace(snapshot_times=(0.3, 0.3))
    late = scene.replace(snapshot_times=(100.0,))  # past the schedule: loads (a run may go past it), not taken
    assert "t100s" not in [n for n, _ in step_table(late).snapshots]
    assert "t100s" in [n for n, _ in step_table(late, 100.5).snapshots]


def test_a_snapshot_time_past_the_run_is_noted(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """A snapshot time the run ends before (the schedule's end, or a shorter --duration): one note, the run goes on."""
    scene = tmp_path / "late.toml"
    text = resources.files("aca_warp.data").joinpath("multiscale.toml").read_text()
    scene.write_text(text.replace("times = []", "times = [0.3, 100.0]", 1))
    argv = ["lf", str(scene), "-o", str(tmp_path / "o.h5"), "--no-progress", "--duration", "0.5"]
    assert main(argv) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["aca-warp: note: the run ends at 0.5 s, before the snapshot time(s) 100 s of the scene: not taken"]


@pytest.mark.parametrize("key", ["T_amb", "T_c", "T_kill"])
def test_an_absolute_temperature_of_zero_is_refused(key) -> None:
    """0 typed for 0 °C: absolute zero, which the plausible range (that leaves 0 to the checks after it) would pass."""
    assert f"lf.{key} = 0 K is absolute zero" in refused(preset(lf={key: 0.0}))


def test_snapshot_applications_must_be_a_bool() -> None:
    assert "snapshots.applications must be true or false, got 'no'" in refused(preset(snapshots={"applications": "no"}))
    assert not lf_scene_from_dict(preset(snapshots={"applications": False})).snapshot_applications


def test_duplicate_snapshot_time_at_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """Exit 2 (bad input, not a disk fault) with one line naming the time, no file and no .partial."""
    s = tmp_path / "lf.toml"
    text = resources.files("aca_warp.data").joinpath("multiscale.toml").read_text()
    s.write_text(text.replace("times = []", "times = [0.5, 0.5]", 1))
    capsys.readouterr()
    assert main(["lf", str(s), "-o", str(tmp_path / "out.h5"), "--no-progress"]) == 2
    err = error_lines(capsys.readouterr().err)
    assert len(err) == 1 and "snapshots.times lists 0.5 s twice" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lf.toml"]


# ----------------------------------------------------------------------------------------------- schedule


def test_a_schedule_needs_a_loaded_application_on_a_sliding_disc() -> None:
    """Pauses only, or loads on a disc at rest only, are refused in the words of an empty schedule."""
    rule = "an LF scene needs a [[schedule]] with at least one application"
    assert rule in refused(preset(schedule=[]))
    err = refused(preset(schedule=[{"kind": "pause", "duration": 1.5}]))
    assert err.startswith(rule) and err.endswith("this one only pauses"), err
    at_rest = [{**SHORT[0], "sliding_speed": 0.0}, SHORT[1]]
    assert refused(preset(schedule=at_rest)).startswith(rule)
    with pytest.raises(SceneError, match=r"at least one application .*only pauses"):
        LFScene("p", schedule=(Segment("pause", 1.0),))
    assert lf_scene_from_dict(preset(schedule=[SHORT[1], SHORT[0], at_rest[0]])).duration == 2.5


# ----------------------------------------------------------------------------------------------- seeds


def test_seeds_beyond_64_bits_are_refused() -> None:
    """lf.seed from 0 to 2^64 − 1; the bound is named. LFScene.with_seed (what --seed sets) names the option the
    way its reader passes it: ``seed`` from Python, ``--seed`` at the command line."""
    assert lf_scene_from_dict(preset(lf={"seed": 2**64 - 1})).lf.seed == 2**64 - 1
    for seed in (2**64, 99999999999999999999, -1):
        err = refused(preset(lf={"seed": seed}))
        assert err == f"lf.seed must be a non-negative integer below 2^64 = 18446744073709551616, got {seed}", err
    scene = lf_scene_from_dict(preset(patches={"count": 50}))
    seeded = scene.with_seed(7)
    assert seeded.lf.seed == 7 and seeded.patches.count == 50
    assert all((getattr(seeded.patches, k) == getattr(scene.patches, k)).all() for k in ("x", "y", "area", "height"))
    for seed in (-1, 2**64, 1.5):
        with pytest.raises(SceneError, match=r"^seed must be a non-negative integer below 2\^64"):
            scene.with_seed(seed)
        with command_line(), pytest.raises(SceneError, match=r"^--seed must be a non-negative integer below 2\^64"):
            scene.with_seed(seed)
    with command_line(), pytest.raises(SceneError, match=r"^lf\.seed must"):
        lf_scene_from_dict(preset(lf={"seed": -1}))  # the scene file's key stays the key


def test_a_seed_beyond_64_bits_at_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    capsys.readouterr()
    out = tmp_path / "out.h5"
    assert main(["lf", "multiscale", "-o", str(out), "--no-progress", "--seed", "99999999999999999999"]) == 2
    err = error_lines(capsys.readouterr().err)
    assert len(err) == 1 and "below 2^64 = 18446744073709551616" in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_the_preset_loads() -> None:
    scene = load_lf_scene("multiscale")
    assert scene.duration == 55.0 and scene.lf == LFConstants(seed=1)


def test_an_hf_scene_of_a_snapshot_in_a_pause_is_refused(tmp_path: Path) -> None:
    """A snapshot taken in a pause (no load, the disc at rest) gives no HF scene: its run would have no friction;
    an application's snapshot does."""
    from aca_warp.lf.commands import run_lf
    from aca_warp.lf.io import scene_from_snapshot

    out = tmp_path / "lf.h5"
    run_lf(lf_scene_from_dict(preset(schedule=SHORT, snapshots={"times": [1.2]}, patches={"count": 50})), out)
    with pytest.raises(SceneError, match=r"snapshot 't1.2s' was taken with the pad unloaded or the disc at rest"):
        scene_from_snapshot(out, "t1.2s")
    assert scene_from_snapshot(out, "app1_end").normal_force > 0
