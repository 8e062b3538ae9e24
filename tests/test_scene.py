"""Tests of aca_warp.scene: validation errors, presets against the paper's numbers, TOML and HDF5 round trips.

Every invalid input must raise :class:`aca_warp.common.errors.SceneError` with a message that names the
offending item (docs/model.md §1–2, the presets table §2.9; paper Table 1 and §3.1–3.2).
"""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest

from aca_warp.common.errors import SceneError
from aca_warp.scene import (
    Friction,
    Growth,
    Initial,
    Material,
    Matrix,
    Pad,
    Patches,
    PatchGenerator,
    Record,
    Scene,
    load_scene,
    overlapping_pairs,
    preset,
    read_patch_file,
    scene_from_dict,
    write_patch_file,
)

# angle from +y of a 0.05 mm² patch centre at r = 0.13 m whose disc crosses the straight +x edge by half its radius
EDGE_INSIDE = math.radians(81.5 / 2) - 0.5 * math.sqrt(5e-8 / math.pi) / 0.13

PAPER = {  # docs/model.md §2.9: area range [m²], M, F_N [N]; height spread [m] (docs/presets.md)
    "hf1": ((2.0e-8, 8.0e-8), 0.8, 487.2, 2.42e-7),
    "hf2": ((5.0e-7, 2.0e-6), 0.8, 12370.0, 1.23e-6),
    "hf3": ((2.0e-8, 8.0e-8), 0.4, 487.2, 2.42e-7),
    "hf4": ((5.0e-7, 2.0e-6), 0.4, 12370.0, 1.23e-6),
    "varying_area": ((2.0e-8, 8.0e-8), 0.8, 12370.0, 2.42e-7),
}
PAPER.update({f"{k}_equal": (*v[:3], 0.0) for k, v in list(PAPER.items())})  # the same with equal heights


def small_patches(**changes) -> Patches:
    """Three well separated 0.05 mm² patches near the mean radius on +y, heights 3 µm."""
    d = {
        "x": np.array([-2.0e-3, 0.0, 2.0e-3]),
        "y": np.array([0.13, 0.13, 0.131]),
        "area": np.full(3, 5.0e-8),
        "height": np.full(3, 3.0e-6),
    }
    d.update(changes)
    return Patches(**d)


def small_scene(**changes) -> Scene:
    """A valid three-patch scene on the default pad."""
    return Scene(name="small", pad=Pad(), patches=small_patches(), **changes)


def small_doc(**tables) -> dict:
    """A TOML-shaped dict of a small generated scene; ``tables`` replace or add whole tables."""
    doc = {
        "scene": {"name": "doc"},
        "load": {"normal_force": 10.0},
        "patches": {"count": 20, "area_min": 2.0e-8, "area_max": 8.0e-8, "height": 3.0e-6, "seed": 4},
        "record": {"sample_dt": 1.0e-7},
        "run": {"duration": 1.0e-5},
    }
    doc.update(tables)
    return doc


# ------------------------------------------------------------------------------------------ valid scenes


def test_small_scene_is_valid_and_fresh_matrix_is_derived():
    """A small Python scene validates; its fresh matrix is the uncovered pad area at elevation 0."""
    s = small_scene()
    assert s.patches.count == 3
    assert s.matrix.is_flat
    assert s.matrix.area[0] == pytest.approx(Pad().area - 3 * 5.0e-8, rel=1e-12)
    assert s.matrix.height[0] == 0.0
    assert Pad().r_inner < s.matrix.radius[0] < Pad().r_outer


def test_replace_with_new_patches_rebuilds_the_fresh_matrix():
    """New patches without a new matrix get a fresh matrix (not the old one) and lose the old origin."""
    s = preset("hf1")
    p = s.patches
    fewer = Patches(x=p.x[:100], y=p.y[:100], area=p.area[:100], height=p.height[:100])
    t = s.replace(patches=fewer)
    assert t.matrix.area[0] == pytest.approx(Pad().area - fewer.area.sum(), rel=1e-12)
    assert t.origin is None
    assert s.replace(duration=2e-3).origin == s.origin  # other changes keep the patch source


# ------------------------------------------------------------------------------------------ numbers


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize(
    "make, match",
    [
        (lambda v: small_scene(normal_force=v), "load.normal_force"),
        (lambda v: small_scene(duration=v), "run.duration"),
        (lambda v: small_scene(angular_velocity=v), "disc.angular_velocity"),
        (lambda v: Record(sample_dt=v), "record.sample_dt"),
        (lambda v: Material(K_T=v), "material.K_T"),
        (lambda v: Material(K_N=v), "material.K_N"),
        (lambda v: Material(K_C=v), "material.K_C"),
        (lambda v: Material(damping_ratio=v), "material.damping_ratio"),
        (lambda v: Material(mass_per_area=v), "material.mass_per_area"),
        (lambda v: Material(matrix_stiffness=v), "material.matrix_stiffness"),
        (lambda v: Material(coupling_radius=v), "material.coupling_radius"),
        (lambda v: Friction(M=v), "friction.M"),
        (lambda v: Friction(mu_pad=v), "friction.mu_pad"),
        (lambda v: Friction(slope=v), "friction.slope"),
        (lambda v: Friction(decay=v), "friction.decay"),
        (lambda v: Initial(perturbation=v), "initial.perturbation"),
        (lambda v: Initial(displacement_perturbation=v), "initial.displacement_perturbation"),
        (lambda v: PatchGenerator(height_spread=v), "patches.height_spread"),
        (lambda v: PatchGenerator(height_spread=1e-7, height_truncation=v), "patches.height_truncation"),
        (lambda v: Growth(increment=v), "growth.increment"),
        (lambda v: Pad(r_outer=v), "pad.r_outer"),
    ],
)
def test_non_finite_values_are_rejected(make, match, bad):
    """NaN and ±inf in any scalar of a scene are refused, naming the field."""
    with pytest.raises(SceneError, match=rf"{match}.*finite"):
        make(bad)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: small_scene(normal_force=-1.0), r"load\.normal_force must be >= 0"),
        (lambda: small_scene(duration=-1e-3), r"run\.duration must be > 0"),
        (lambda: small_scene(duration=0.0), r"run\.duration must be > 0"),
        (lambda: Record(sample_dt=-1e-7), r"record\.sample_dt must be > 0"),
        (lambda: Record(sample_dt=0.0), r"record\.sample_dt must be > 0"),
        (lambda: Material(K_T=-1.0), r"material\.K_T must be > 0"),
        (lambda: Material(K_N=0.0), r"material\.K_N must be > 0"),
        (lambda: Material(K_C=-7.96e8), r"material\.K_C must be > 0"),
        (lambda: Material(mass_per_area=-37.5), r"material\.mass_per_area must be > 0"),
        (lambda: Material(matrix_stiffness=-1.0), r"material\.matrix_stiffness must be > 0"),
        (lambda: Material(damping_ratio=-1e-6), r"material\.damping_ratio must be >= 0"),
        (lambda: Material(coupling_radius=-1e-3), r"material\.coupling_radius must be >= 0"),
        (lambda: Friction(M=-0.8), r"friction\.M must be >= 0"),
        (lambda: Friction(mu_pad=-0.3), r"friction\.mu_pad must be >= 0"),
        (lambda: Friction(slope=0.0), r"friction\.slope must be > 0"),
        (lambda: Friction(decay=-0.25), r"friction\.decay must be >= 0"),
        (lambda: Initial(perturbation=-0.1), r"initial\.perturbation must be >= 0"),
        (lambda: Initial(seed=-1), r"initial\.seed must be a non-negative integer"),
        (lambda: Growth(interval=0.0), r"growth\.interval must be > 0"),
        (lambda: Growth(increment=-1e-9), r"growth\.increment must be >= 0"),
        (lambda: Pad(r_inner=0.2, r_outer=0.1), r"pad\.r_outer .* must exceed pad\.r_inner"),
        (lambda: Pad(span_deg=400.0), r"pad\.span_deg must be <= 360"),
        (lambda: Pad(span_deg=0.0), r"pad\.span_deg must be > 0"),
        (
            lambda: small_scene(record=Record(sample_dt=1e-2)),
            r"\(record\.sample_dt\) exceeds the duration .* \(run\.duration\)",
        ),
        (lambda: Material(K_T="big"), r"material\.K_T must be a number"),
        (lambda: Material(K_T=True), r"material\.K_T must be a number"),
    ],
)
def test_negative_and_out_of_range_values_are_rejected(make, match):
    """Negative (or zero, where a positive value is needed) constants, loads and times are refused."""
    with pytest.raises(SceneError, match=match):
        make()


@pytest.mark.parametrize(
    "changes, match",
    [
        ({"area": np.array([5e-8, -5e-8, 5e-8])}, r"patch areas must be > 0 .*patch 1"),
        ({"area": np.array([5e-8, 5e-8, 0.0])}, r"patch areas must be > 0 .*patch 2"),
        ({"height": np.array([3e-6, 3e-6, -1e-9])}, r"patch heights must be >= 0 .*patch 2"),
        ({"area": np.array([5e-8, np.nan, 5e-8])}, r"patches\.area has a non-finite value at patch 1"),
        ({"height": np.array([np.inf, 3e-6, 3e-6])}, r"patches\.height has a non-finite value at patch 0"),
        ({"x": np.array([-2e-3, np.nan, 2e-3])}, r"patches\.x has a non-finite value at patch 1"),
        ({"y": np.array([0.13, 0.13, -np.inf])}, r"patches\.y has a non-finite value at patch 2"),
        ({"x": np.array([-2e-3, 0.0])}, r"equal lengths"),
        ({"area": np.full(4, 5e-8)}, r"equal lengths"),
        ({"x": np.zeros((3, 1))}, r"patches\.x must be one-dimensional"),
        ({"x": np.zeros(0), "y": np.zeros(0), "area": np.zeros(0), "height": np.zeros(0)}, r"at least one patch"),
    ],
)
def test_bad_patch_arrays_are_rejected(changes, match):
    """Non-positive areas, negative heights, non-finite values and arrays of unequal length are refused."""
    with pytest.raises(SceneError, match=match):
        small_patches(**changes)


# ------------------------------------------------------------------------------------------ geometry


def test_overlapping_patches_are_rejected():
    """Two patches closer than the sum of their radii make the scene invalid (never k_ij → ∞)."""
    r = math.sqrt(5e-8 / math.pi)
    p = small_patches(x=np.array([-2e-3, 0.0, 1.9 * r]), y=np.array([0.13, 0.13, 0.13]))
    assert overlapping_pairs(p).tolist() == [[1, 2]]
    with pytest.raises(SceneError, match=r"1 pair\(s\) of patches overlap, first patches 1 and 2"):
        Scene(name="overlap", pad=Pad(), patches=p)
    # just touching (2.01 r) is allowed
    p_ok = small_patches(x=np.array([-2e-3, 0.0, 2.01 * r]), y=np.array([0.13, 0.13, 0.13]))
    assert len(overlapping_pairs(p_ok)) == 0
    Scene(name="touching", pad=Pad(), patches=p_ok)


def test_identical_positions_overlap():
    """Two patches at the same centre (D0 = 0) are caught as an overlap."""
    p = small_patches(x=np.array([0.0, 0.0, 2e-3]))
    with pytest.raises(SceneError, match="overlap"):
        Scene(name="same", pad=Pad(), patches=p)


@pytest.mark.parametrize(
    "x, y, why",
    [
        (0.0, 0.099, "inside the inner radius"),
        (0.0, 0.1001, "straddles the inner radius"),
        (0.0, 0.1599, "straddles the outer radius"),
        (0.0, 0.17, "beyond the outer radius"),
        (0.0, -0.13, "opposite side of the disc"),
        (0.13 * math.sin(math.radians(41.0)), 0.13 * math.cos(math.radians(41.0)), "beyond the +x edge"),
        (0.13 * math.sin(EDGE_INSIDE), 0.13 * math.cos(EDGE_INSIDE), "centre inside, disc straddles the +x edge"),
        (-0.13 * math.sin(math.radians(45.0)), 0.13 * math.cos(math.radians(45.0)), "beyond the -x edge"),
    ],
)
def test_patches_outside_the_pad_are_rejected(x, y, why):
    """A patch disc reaching beyond the annulus or the angular span (±40.75°) is refused."""
    p = small_patches(x=np.array([-2e-3, 0.0, x]), y=np.array([0.13, 0.12, y]))
    with pytest.raises(SceneError, match=r"1 patch\(es\) lie \(partly\) outside the pad, first is patch 2"):
        Scene(name=why, pad=Pad(), patches=p)


def test_patch_just_inside_the_angular_edge_is_accepted():
    """A patch whose disc just fits inside the straight edge of the sector is valid."""
    r = math.sqrt(5e-8 / math.pi)
    half = math.radians(81.5 / 2)
    rr = 0.13
    ang = half - 1.05 * r / rr  # edge distance rr sin(half − ang) ≈ 1.05 r
    p = small_patches(x=np.array([-2e-3, 0.0, rr * math.sin(ang)]), y=np.array([0.13, 0.12, rr * math.cos(ang)]))
    Scene(name="edge", pad=Pad(), patches=p)


# ------------------------------------------------------------------------------------------ record, initial


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"patches": ("acceleration",)}, r"record\.patches: unknown variable 'acceleration'"),
        ({"patches": ("velocity", "u")}, r"unknown variable 'u'"),
        ({"window": (1e-5, 1e-6)}, r"record\.window end must exceed its start"),
        ({"window": (1e-5, 1e-5)}, r"record\.window end must exceed its start"),
        ({"window": (-1e-6, 1e-5)}, r"record\.window start must be >= 0"),
        ({"window": (0.0, math.nan)}, r"record\.window end must exceed its start"),
        ({"window": (0.0,)}, r"record\.window must be \[start, end\]"),
        ({"window": (0.0, 1.0, 2.0)}, r"record\.window must be \[start, end\]"),
        ({"decimation": 0}, r"record\.decimation must be a positive integer"),
        ({"decimation": 2.0}, r"record\.decimation must be a positive integer"),
        ({"decimation": True}, r"record\.decimation must be a positive integer"),
    ],
)
def test_bad_record_options_are_rejected(kwargs, match):
    """Unknown per-patch variables, empty or reversed windows and non-positive decimation are refused."""
    with pytest.raises(SceneError, match=match):
        Record(**kwargs)


def test_non_numeric_window_end_is_a_scene_error():
    """A non-numeric window end must be a SceneError like every other bad value."""
    try:
        Record(window=(0.0, "x"))
    except SceneError:
        return
    except Exception as e:  # noqa: BLE001 - documenting the wrong exception type
        raise AssertionError(f"raised {type(e).__name__}: {e}") from None
    raise AssertionError("no error raised")


@pytest.mark.parametrize(
    "area, radius, height",
    [
        ([-1.0e-3], [0.13], [0.0]),
        ([1.0e-3, 1.0e-3], [0.13], [0.0]),
        ([1.0e-3], [0.13], [math.nan]),
    ],
)
def test_bad_matrix_cells_are_rejected(area, radius, height):
    """A scene given matrix cells with a negative area, a NaN elevation or ragged arrays must be refused."""
    with pytest.raises(SceneError):
        Scene(
            name="m",
            pad=Pad(),
            patches=small_patches(),
            matrix=Matrix(np.array(area), np.array(radius), np.array(height)),
        )


def test_unknown_initial_state_is_rejected():
    """Only 'rest' and 'equilibrium' are initial states."""
    with pytest.raises(SceneError, match=r"initial\.state must be one of rest, equilibrium, got 'moving'"):
        Initial(state="moving")


# ------------------------------------------------------------------------------------------ TOML documents


def test_small_doc_is_valid():
    """The base document used below builds a scene with 20 generated patches and the given load."""
    s = scene_from_dict(small_doc())
    assert s.name == "doc"
    assert s.patches.count == 20
    assert s.normal_force == 10.0
    assert s.angular_velocity == pytest.approx(10.0 / 0.13, rel=1e-12)


@pytest.mark.parametrize(
    "doc, match",
    [
        ({"solver": {"dt": 1e-9}}, r"unknown table \[solver\]; allowed: \[scene\]"),
        ({"load": {"normal_force": 10.0, "pressure": 1.0}}, r"unknown key 'pressure' in \[load\]"),
        ({"pad": {"radius": 0.1}}, r"unknown key 'radius' in \[pad\]"),
        ({"material": {"K_X": 1.0}}, r"unknown key 'K_X' in \[material\]"),
        ({"record": {"sample_dt": 1e-7, "every": 2}}, r"unknown key 'every' in \[record\]"),
        ({"load": 5.0}, r"\[load\] must be a table"),
        ({"disc": {"sliding_speed": 10.0, "angular_velocity": 70.0}}, r"sliding_speed or angular_velocity, not both"),
        ({"disc": {"sliding_speed": math.nan}}, r"disc\.sliding_speed must be finite"),
        ({"load": {"normal_force": -5.0}}, r"load\.normal_force must be >= 0"),
        ({"load": {"normal_force": math.inf}}, r"load\.normal_force must be finite"),
        ({"run": {"duration": -1.0}}, r"run\.duration must be > 0"),
        ({"record": {"sample_dt": -1e-7}}, r"record\.sample_dt must be > 0"),
        ({"record": {"sample_dt": 1e-7, "patches": "velocity"}}, r"record\.patches must be a list"),
        ({"record": {"sample_dt": 1e-7, "patches": ["speed"]}}, r"unknown variable 'speed'"),
        ({"record": {"sample_dt": 1e-7, "window": [2e-6, 1e-6]}}, r"record\.window end must exceed its start"),
        ({"record": {"sample_dt": 1e-7, "decimation": 0}}, r"record\.decimation must be a positive integer"),
        ({"initial": {"state": "spinning"}}, r"initial\.state must be one of"),
        ({"friction": {"M": -0.8}}, r"friction\.M must be >= 0"),
        ({"friction": {"slope": 0.0}}, r"friction\.slope must be > 0"),
        ({"material": {"K_T": 0.0}}, r"material\.K_T must be > 0"),
        ({"growth": {"interval": -1.0}}, r"growth\.interval must be > 0"),
        ({"patches": {"count": 0}}, r"patches\.count must be a positive integer"),
        ({"patches": {"count": 10.5}}, r"patches\.count must be a positive integer"),
        ({"patches": {"count": 5, "area_min": -1e-8}}, r"patches\.area_min must be > 0"),
        ({"patches": {"count": 5, "area_min": 8e-8, "area_max": 2e-8}}, r"patches\.area_max .* must be >="),
        ({"patches": {"count": 5, "height": -1e-6}}, r"patches\.height must be >= 0"),
        ({"patches": {"count": 5, "seed": -3}}, r"patches\.seed must be a non-negative integer"),
        ({"pad": {"r_inner": 0.2}}, r"pad\.r_outer .* must exceed pad\.r_inner"),
    ],
)
def test_bad_documents_are_rejected(doc, match):
    """Unknown tables/keys, conflicting disc keys and bad values of a TOML-shaped document are SceneErrors."""
    with pytest.raises(SceneError, match=match):
        scene_from_dict(small_doc(**doc))


def test_scalar_window_in_document_is_a_scene_error():
    """``window = 1.0`` (not a [start, end] pair) must be reported as a SceneError."""
    try:
        scene_from_dict(small_doc(record={"sample_dt": 1e-7, "window": 1.0}))
    except SceneError:
        return
    except Exception as e:  # noqa: BLE001 - documenting the wrong exception type
        raise AssertionError(f"raised {type(e).__name__}: {e}") from None
    raise AssertionError("no error raised")


def test_unknown_table_and_key_in_toml_file(tmp_path):
    """load_scene on TOML files with an unknown table or key names the culprit."""
    f = tmp_path / "bad_table.toml"
    f.write_text('[scene]\nname = "x"\n[bogus]\na = 1\n')
    with pytest.raises(SceneError, match=r"unknown table \[bogus\]"):
        load_scene(f)
    f = tmp_path / "bad_key.toml"
    f.write_text("[load]\nnormal_force = 10.0\nnormal_froce = 10.0\n")
    with pytest.raises(SceneError, match=r"unknown key 'normal_froce' in \[load\]"):
        load_scene(f)


def test_unparsable_toml_and_missing_scene(tmp_path):
    """A TOML syntax error and a path that is neither a preset nor a file are SceneErrors."""
    f = tmp_path / "broken.toml"
    f.write_text("[load\nnormal_force = 1\n")
    with pytest.raises(SceneError, match=r"cannot parse .*broken\.toml"):
        load_scene(f)
    with pytest.raises(SceneError, match=r"neither a preset .* nor an existing TOML file"):
        load_scene(tmp_path / "nothing.toml")


def test_unknown_preset():
    """preset() names the allowed presets."""
    names = "hf1, hf2, hf3, hf4, varying_area, hf1_equal, hf2_equal, hf3_equal, hf4_equal, varying_area_equal"
    with pytest.raises(SceneError, match=rf"unknown preset 'hf5'; choose from {names}$"):
        preset("hf5")


def test_generator_that_cannot_place_its_patches():
    """A generator asked for patches wider than the pad's radial extent gives up with a clear message."""
    big = math.pi * 0.035**2  # diameter 70 mm > the 60 mm annulus
    with pytest.raises(SceneError, match=r"could not place 2 non-overlapping patches .* \(placed 0\)"):
        scene_from_dict(small_doc(patches={"count": 2, "area_min": big, "area_max": big}), allow_implausible=True)
    with pytest.raises(SceneError, match=r"could not place 400 non-overlapping patches"):
        PatchGenerator(count=400, area_min=1e-4, area_max=1e-4).generate(Pad())


# ------------------------------------------------------------------------------------------ patch files


def test_patch_file_round_trip_through_toml(tmp_path):
    """``[patches] file = "p.h5"`` is read relative to the TOML file and gives back the written patches."""
    src = PatchGenerator(count=40, seed=11).generate(Pad())
    write_patch_file(tmp_path / "p.h5", src)
    with h5py.File(tmp_path / "p.h5") as f:
        assert f["area"].attrs["unit"] == "m2"
    (tmp_path / "scene.toml").write_text(
        '[scene]\nname = "from_file"\n[load]\nnormal_force = 20.0\n[patches]\nfile = "p.h5"\n'
        "[record]\nsample_dt = 1e-7\n[run]\nduration = 1e-5\n"
    )
    s = load_scene(tmp_path / "scene.toml")
    assert s.name == "from_file"
    for k in ("x", "y", "area", "height"):
        np.testing.assert_array_equal(getattr(s.patches, k), getattr(src, k))
    assert s.patches.source.endswith("p.h5")
    # read_patch_file directly too
    back = read_patch_file(tmp_path / "p.h5")
    np.testing.assert_array_equal(back.area, src.area)


def test_missing_patch_file(tmp_path):
    """A [patches] file that does not exist is reported with its resolved path."""
    (tmp_path / "s.toml").write_text('[patches]\nfile = "nope.h5"\n')
    with pytest.raises(SceneError, match=r"patch file not found: .*nope\.h5"):
        load_scene(tmp_path / "s.toml")
    with pytest.raises(SceneError, match="patch file not found"):
        read_patch_file(tmp_path / "absent.h5")


@pytest.mark.parametrize(
    ("height", "match"),
    [(None, r"lacks dataset\(s\) height"), (np.full(5, 3e-6), "equal lengths")],
    ids=["lacking-height", "unequal-lengths"],
)
def test_malformed_patch_file(tmp_path, height, match):
    """A patch file without a ``height`` dataset names the missing dataset; datasets of unequal length are
    refused."""
    p = small_patches()
    with h5py.File(tmp_path / "p.h5", "w") as f:
        for k in ("x", "y", "area"):
            f.create_dataset(k, data=getattr(p, k))
        if height is not None:
            f.create_dataset("height", data=height)
    with pytest.raises(SceneError, match=match):
        read_patch_file(tmp_path / "p.h5")


def test_patch_file_that_is_not_hdf5(tmp_path):
    """A file that is not HDF5 is a SceneError, not an OSError."""
    (tmp_path / "p.h5").write_text("not hdf5")
    with pytest.raises(SceneError, match=r"cannot read patch file"):
        read_patch_file(tmp_path / "p.h5")


def test_patch_file_with_generator_keys(tmp_path):
    """``file`` cannot be combined with generator keys such as ``count`` or ``seed``."""
    write_patch_file(tmp_path / "p.h5", small_patches())
    with pytest.raises(SceneError, match=r"cannot be combined with generator keys count, seed"):
        scene_from_dict(small_doc(patches={"file": "p.h5", "count": 3, "seed": 1}), base_dir=tmp_path)


def test_overlapping_patches_from_file(tmp_path):
    """Patches read from a file are validated like any others."""
    r = math.sqrt(5e-8 / math.pi)
    write_patch_file(tmp_path / "p.h5", small_patches(x=np.array([0.0, 1.5 * r, 2e-3]), y=np.full(3, 0.13)))
    with pytest.raises(SceneError, match="overlap"):
        scene_from_dict(small_doc(patches={"file": "p.h5"}), base_dir=tmp_path)


# ------------------------------------------------------------------------------------------ generator


def test_generator_is_seeded():
    """Same seed → identical patches; a different seed → different positions and areas."""
    g = PatchGenerator(count=200, seed=7)
    a, b = g.generate(Pad()), g.generate(Pad())
    for k in ("x", "y", "area", "height"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    c = PatchGenerator(count=200, seed=8).generate(Pad())
    assert not np.array_equal(a.x, c.x)
    assert not np.array_equal(np.sort(a.area), np.sort(c.area))
    d1 = scene_from_dict(small_doc()).patches
    d2 = scene_from_dict(small_doc()).patches
    np.testing.assert_array_equal(d1.x, d2.x)


# ------------------------------------------------------------------------------------------ presets


@pytest.fixture(scope="module")
def presets() -> dict[str, Scene]:
    """All presets, loaded once."""
    return {name: preset(name) for name in PAPER}


@pytest.mark.parametrize("name", list(PAPER))
def test_presets_match_the_paper(presets, name):
    """Presets: 1758 patches in the paper's area range, M and F_N per Table 1, default pad, 10 m/s."""
    s = presets[name]
    (a_lo, a_hi), M, load, spread = PAPER[name]
    p = s.patches
    assert s.name == name
    assert p.count == 1758
    assert p.area.min() >= a_lo and p.area.max() <= a_hi
    # uniform over the range: the extremes are close to its ends and the mean is near the middle
    assert p.area.min() < a_lo + 0.01 * (a_hi - a_lo) and p.area.max() > a_hi - 0.01 * (a_hi - a_lo)
    assert p.area.mean() == pytest.approx(0.5 * (a_lo + a_hi), rel=0.03)
    if spread == 0.0:
        np.testing.assert_array_equal(p.height, 3.0e-6)
    else:  # truncated normal: mean 3 µm, within ±2 spreads, reaching close to both cuts
        assert p.height.min() >= 3.0e-6 - 2 * spread and p.height.max() <= 3.0e-6 + 2 * spread
        assert p.height.min() < 3.0e-6 - 1.9 * spread and p.height.max() > 3.0e-6 + 1.9 * spread
        assert p.height.mean() == pytest.approx(3.0e-6, abs=4 * spread / math.sqrt(p.count))
    assert s.friction.M == M
    assert s.friction.mu_pad == 0.3
    assert s.normal_force == load
    assert s.pad.area == pytest.approx(0.0111, rel=0.01)
    assert s.pad.mean_radius == pytest.approx(0.13)
    assert s.angular_velocity == pytest.approx(10.0 / 0.13, rel=1e-12)
    assert s.sliding_speed == pytest.approx(10.0, rel=1e-12)
    assert s.material == Material()
    assert s.initial.state == "rest"
    assert len(overlapping_pairs(p)) == 0
    assert np.all(s.pad.contains_disc(p.x, p.y, p.radius))
    # masses 0.75–3.0 mg for the HF1 size range (paper §2.1.2)
    if a_hi < 1e-7:
        m = s.material.mass_per_area * p.area
        assert m.min() >= 0.75e-6 and m.max() <= 3.0e-6
    assert (s.growth is not None) == name.startswith("varying_area")


def test_varying_area_growth_is_eq10():
    """varying_area: Eq. 10 in SI, ΔA = 1e-9 m · √A every 2.02e-7 s, over 0.36 s."""
    s = preset("varying_area")
    assert s.growth == Growth(increment=1.0e-9, interval=2.02e-7)
    assert s.duration == 0.36
    # Eq. 10 in mm²: dA = 1e-6 sqrt(A) ⇔ 1e-9 m sqrt(A[m²]) in m²
    a_mm2 = 0.05
    assert 1e-6 * math.sqrt(a_mm2) * 1e-6 == pytest.approx(1e-9 * math.sqrt(a_mm2 * 1e-6), rel=1e-12)


def test_presets_are_reproducible_and_share_positions():
    """Presets are generated from seed 1: loading twice gives identical patches; hf1, hf3 and varying_area share
    positions, areas and heights, hf1_equal their positions and areas."""
    a, b = preset("hf1"), preset("hf1")
    np.testing.assert_array_equal(a.patches.x, b.patches.x)
    np.testing.assert_array_equal(a.patches.height, b.patches.height)
    for other in ("hf3", "varying_area", "hf1_equal"):
        o = preset(other).patches
        np.testing.assert_array_equal(a.patches.x, o.x)
        np.testing.assert_array_equal(a.patches.area, o.area)
        if other != "hf1_equal":
            np.testing.assert_array_equal(a.patches.height, o.height)
    np.testing.assert_array_equal(preset("hf2").patches.height, preset("hf4").patches.height)


def test_load_scene_accepts_preset_names():
    """load_scene('hf2') is the preset."""
    s = load_scene("hf2")
    assert s.name == "hf2" and s.normal_force == 12370.0


def test_sliding_speed_and_angular_velocity_keys():
    """[disc] sliding_speed is measured at the mean radius; angular_velocity is taken as is."""
    s = scene_from_dict(small_doc(disc={"sliding_speed": 5.0}))
    assert s.angular_velocity == pytest.approx(5.0 / 0.13, rel=1e-12)
    s = scene_from_dict(small_doc(disc={"angular_velocity": 50.0}))
    assert s.angular_velocity == 50.0
    assert s.sliding_speed == pytest.approx(50.0 * 0.13, rel=1e-12)


def test_pairs_within_counts_as_a_kd_tree_does():
    """The NumPy count of point pairs within a radius (the sweep's memory estimate per pad) equals SciPy's k-d tree
    count, distance ≤ radius included: random points of several densities, a pair exactly at the radius, and the
    hf1 preset's patches at its coupling radius."""
    from scipy.spatial import cKDTree

    from aca_warp.scene.parts import pairs_within

    def kd(x: np.ndarray, y: np.ndarray, r: float) -> int:
        return len(cKDTree(np.column_stack([x, y])).query_pairs(r))

    rng = np.random.default_rng(7)
    for n, r in [(2, 1.0), (40, 0.3), (500, 1e-3), (2000, 4e-3)]:
        x, y = rng.uniform(0, 0.05, n), rng.uniform(0, 0.1, n)
        assert pairs_within(x, y, r) == kd(x, y, r) > 0
    x, y = np.array([0.0, 0.25, 0.5, 3.0]), np.array([0.0, 0.0, 0.0, 0.0])  # 0.25 apart exactly: in
    assert pairs_within(x, y, 0.25) == kd(x, y, 0.25) == 2
    assert pairs_within(np.zeros(1), np.zeros(1), 1.0) == 0
    s = preset("hf1")
    p = s.patches
    assert pairs_within(p.x, p.y, s.material.coupling_radius) == kd(p.x, p.y, s.material.coupling_radius) > 1000


def _one_trial_at_a_time(gen, pad, max_tries=200):
    """Random sequential addition as first written: one scalar draw pair and one bounds test per trial (the
    reference the generator's blocked trials and native loop must reproduce bit for bit). Returns the centres
    (count, 2) [m] and how many patches were placed before one found no place in ``max_tries`` × 10 trials (then
    the loop stops there, as the generator gives up there)."""
    rng = np.random.default_rng(gen.seed)
    rad = np.sqrt(rng.uniform(gen.area_min, gen.area_max, gen.count) / np.pi)
    cell, grid, xy = max(2.0 * rad.max(), 1e-4), {}, np.zeros((gen.count, 2))
    lo2, hi2 = pad.r_inner**2, pad.r_outer**2
    for i in range(gen.count):
        for _ in range(max_tries * 10):
            r = math.sqrt(rng.uniform(lo2, hi2))
            th = math.pi / 2 + rng.uniform(-pad.half_span, pad.half_span)
            p = (r * math.cos(th), r * math.sin(th))
            if not pad.contains_disc(np.array(p[0]), np.array(p[1]), np.array(rad[i])):
                continue
            cx, cy = int(math.floor(p[0] / cell)), int(math.floor(p[1] / cell))
            near = [j for gx in (cx - 1, cx, cx + 1) for gy in (cy - 1, cy, cy + 1) for j in grid.get((gx, gy), ())]
            if all(math.hypot(p[0] - xy[j, 0], p[1] - xy[j, 1]) >= rad[i] + rad[j] for j in near):
                xy[i] = p
                grid.setdefault((cx, cy), []).append(i)
                break
        else:
            return xy, i
    return xy, gen.count


def _placed_one_trial_at_a_time(gen, pad):
    """The centres of :func:`_one_trial_at_a_time`, every patch placed."""
    xy, placed = _one_trial_at_a_time(gen, pad)
    assert placed == gen.count
    return xy


@pytest.mark.parametrize(("name", "count", "seed"), [("hf1", 600, 1), ("hf1", 600, 7), ("hf3", 300, 2)])
def test_blocked_trials_place_the_patches_of_one_trial_at_a_time(name, count, seed):
    """The generator draws its trials in blocks and tests a block's bounds at once: the same centres, bit for bit,
    as one trial at a time (also on a full ring, where the straight edges drop out)."""
    from aca_warp.scene.generator import PatchGenerator
    from aca_warp.scene.parts import Pad

    for pad in (preset(name).pad, Pad(r_inner=0.05, r_outer=0.08, span_deg=360.0)):
        gen = PatchGenerator(count=count, seed=seed)
        rng = np.random.default_rng(seed)
        rad = np.sqrt(rng.uniform(gen.area_min, gen.area_max, count) / np.pi)
        got = gen._place(pad, rng, rad, 200)
        assert got.tobytes() == _placed_one_trial_at_a_time(gen, pad).tobytes()


def test_native_placement_resumes_and_defers_close_calls(monkeypatch):
    """The native accept / reject loop gives the layouts of one trial at a time when it runs out of trials and must
    draw more (a dense pad), and when it leaves many trials to the host (a wide margin: every close pair is decided
    with ``math.hypot`` there); the host path is taken in the second case."""
    from aca_warp.kernels import placement

    from aca_warp.scene import generator
    from aca_warp.scene.generator import PatchGenerator
    from aca_warp.scene.parts import Pad

    pad = Pad(r_inner=0.1, r_outer=0.104, span_deg=10.0)  # 7.0e-5 m²: 500 patches of ≤ 8e-8 m² fill 0.4 of it
    statuses: list[int] = []
    run = placement.DiscPlacement.run

    def counted(self, *args):
        state = run(self, *args)
        statuses.append(int(state[3]))
        return state

    monkeypatch.setattr(placement.DiscPlacement, "run", counted)
    for seed in (1, 2):
        gen = PatchGenerator(count=500, seed=seed)
        rng = np.random.default_rng(seed)
        rad = np.sqrt(rng.uniform(gen.area_min, gen.area_max, gen.count) / np.pi)
        assert gen._place(pad, rng, rad, 200).tobytes() == _placed_one_trial_at_a_time(gen, pad).tobytes()
    assert placement.MORE_TRIALS in statuses and placement.AMBIGUOUS not in statuses
    deferred = []
    overlaps = generator._overlaps
    monkeypatch.setattr(generator, "_overlaps", lambda *a: deferred.append(a) or overlaps(*a))
    monkeypatch.setattr(placement, "MARGIN", 0.3)
    gen = PatchGenerator(count=300, seed=3)
    rng = np.random.default_rng(3)
    rad = np.sqrt(rng.uniform(gen.area_min, gen.area_max, gen.count) / np.pi)
    hf1 = preset("hf1").pad
    assert gen._place(hf1, rng, rad, 200).tobytes() == _placed_one_trial_at_a_time(gen, hf1).tobytes()
    assert len(deferred) > 5


def test_native_placement_gives_up_where_the_loop_in_python_did(monkeypatch):
    """A pad that jams: the native loop gives up at the same patch as one trial at a time (the message names how
    many it placed); with every disc in one hash bucket (every chain collides) the layout is the same; max_tries
    outside [1, MAX_TRIES] is refused before any draw."""
    import warp as wp
    from aca_warp.kernels import placement

    from aca_warp.scene.generator import MAX_TRIES, PatchGenerator
    from aca_warp.scene.parts import Pad

    pad = Pad(r_inner=0.1, r_outer=0.1006, span_deg=2.0)  # 2.1e-6 m² for 60 patches of 2e-8–8e-8 m²: jams
    for seed, tries in ((4, 2), (5, 1), (6, 3)):
        gen = PatchGenerator(count=60, seed=seed)
        expected = _one_trial_at_a_time(gen, pad, tries)[1]
        assert 0 < expected < 60
        with pytest.raises(SceneError, match=rf"\(placed {expected}\)"):
            gen.generate(pad, max_tries=tries)
    init = placement.DiscPlacement.__init__

    def one_bucket(self, *args):
        init(self, *args)
        self.mask = wp.uint32(0)

    monkeypatch.setattr(placement.DiscPlacement, "__init__", one_bucket)
    hf1 = preset("hf1").pad
    gen = PatchGenerator(count=400, seed=9)
    rng = np.random.default_rng(9)
    rad = np.sqrt(rng.uniform(gen.area_min, gen.area_max, gen.count) / np.pi)
    assert gen._place(hf1, rng, rad, 200).tobytes() == _placed_one_trial_at_a_time(gen, hf1).tobytes()
    for bad in (0, -1, MAX_TRIES + 1, 2.0, True):
        with pytest.raises(SceneError, match=r"max_tries must be an integer in \[1, "):
            gen.generate(hf1, max_tries=bad)


def test_placement_grid_refuses_a_pad_far_larger_than_its_patches():
    """A pad whose outer radius spans 2³⁰ cells of the placement grid or more is refused in one line."""
    from aca_warp.scene.generator import PatchGenerator
    from aca_warp.scene.parts import Pad

    with pytest.raises(SceneError, match="too large against its patches"):
        PatchGenerator(count=2, area_min=1e-12, area_max=1e-12).generate(Pad(r_inner=0.0, r_outer=2e5, span_deg=1.0))


def test_generated_layouts_pass_the_geometry_check_they_skip():
    """The generator marks its layouts as fitting their pad, so a scene does not check them again; the check itself,
    run on them, finds every patch inside the pad and no pair overlapping (hf1 and varying_area counts, a full ring)."""
    from aca_warp.scene.generator import PatchGenerator
    from aca_warp.scene.parts import Pad, overlapping_pairs

    for pad, count, amax in ((preset("hf1").pad, 1758, 8e-8), (Pad(0.05, 0.08, 360.0), 4000, 6e-8)):
        for seed in (1, 2, 3):
            p = PatchGenerator(count=count, area_max=amax, seed=seed).generate(pad)
            assert p.__dict__["_fits"] == pad
            assert pad.contains_disc(p.x, p.y, p.radius).all() and len(overlapping_pairs(p)) == 0
