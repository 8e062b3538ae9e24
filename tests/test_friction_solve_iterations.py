"""scripts/friction_solve_iterations.py: its counting copy of the friction solve returns the kernels' velocity to
the last bit, its zero-slip variant the same root within the solve's tolerance, and the command writes its table."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import warp as wp
from aca_warp.kernels.physics import friction_substep
from scriptload import load_script

from aca_warp.hf.options import NEWTON_TOL

fsi = load_script("friction_solve_iterations")

# hf1's Eq. 4: M/π, slope a [s/m], decay b [s/m]
PAD = {"mu_scale": 0.8 / np.pi, "slope": 200.0, "decay": 0.25}


@wp.kernel(enable_backward=False, module="unique")
def _substep(p: wp.array2d[Any], h: Any, law: wp.array[Any], crossing: int, out: wp.array[Any]):
    """friction_substep per patch i of the rows of ``p``: v, force, mass, damping, normal force, disc speed;
    ``law`` the friction law and tolerance (mu_scale, slope, decay, tol); ``crossing`` its treatment of crossings."""
    i = wp.tid()
    out[i] = friction_substep(
        p[0, i], h, p[2, i], p[3, i], p[4, i], p[1, i], p[5, i], law[0], law[1], law[2], law[3], crossing
    )


def _kernels_substep(patch: dict, h: float, precision: str, crossing: int) -> np.ndarray:
    """The kernels' friction sub-step of every patch of ``patch`` over ``h`` [s], on the CPU."""
    dtype = wp.float32 if precision == "fp32" else wp.float64
    rows = np.stack([patch[k] for k in ("v", "force", "mass", "damping", "normal_force", "disc_speed")])
    law = [PAD["mu_scale"], PAD["slope"], PAD["decay"], NEWTON_TOL[precision]]
    out = wp.zeros(len(patch["v"]), dtype=dtype, device="cpu")
    inputs = [wp.array(rows, dtype=dtype, device="cpu"), dtype(h), wp.array(law, dtype=dtype, device="cpu"), crossing]
    wp.launch(_substep, dim=len(out), inputs=inputs, outputs=[out], device="cpu")
    return out.numpy()


def _patches(n: int = 4000, seed: int = 3) -> dict[str, np.ndarray]:
    """Patches of hf1's scale: sliding, near sticking (slips within ±0.1 m/s) and spring forces up to twice the
    friction force, so that some slips pass through zero in the step."""
    rng = np.random.default_rng(seed)
    vd = rng.uniform(5.0, 12.0, n)
    slip = np.where(rng.random(n) < 0.5, rng.uniform(-0.1, 0.1, n), rng.uniform(0.1, 12.0, n))
    fn = rng.uniform(0.5, 5.0, n)
    mass = rng.uniform(1e-7, 2e-6, n)
    return {
        "v": vd - slip,
        "force": fn * 0.8 * rng.uniform(-2.0, 2.0, n),
        "mass": mass,
        "damping": 2.0 * 0.05 * np.sqrt(1e6 * mass),
        "normal_force": fn,
        "disc_speed": vd,
    }


@pytest.mark.parametrize("precision", ["fp32", "fp64"])
@pytest.mark.parametrize("h", [5e-8, 1e-6])
def test_counting_copy_is_the_kernels_solve(precision: str, h: float) -> None:
    """The script counts the solve the kernels take: its velocity equals friction_substep's bit for bit (at 5e-8 s
    and at 1e-6 s, where θ leaves ½ and the solves bisect), and a zero-slip variant that counts differently lands on
    the same root within the solve's tolerance."""
    patch = _patches()
    kernel = fsi.count(patch, PAD, h, precision, zero_slip=False)
    np.testing.assert_array_equal(kernel["v"], _kernels_substep(patch, h, precision, 0))
    assert not kernel["segment_iterations"].any()
    assert kernel["iterations"].min() >= 1 and kernel["iterations"].max() < 60
    assert kernel["bisections"].max() > 0 or h < 1e-6  # the large step exercises the safeguard
    variant = fsi.count(patch, PAD, h, precision, zero_slip=True)
    scale = h * patch["normal_force"] * 0.8 / patch["mass"]  # the bracket's half width [m/s], at most
    eps = 1e-5 if precision == "fp32" else 1e-8
    assert np.all(np.abs(variant["v"] - kernel["v"]) <= eps * (scale + np.abs(kernel["v"]) * 1e-2))
    assert not np.array_equal(variant["iterations"], kernel["iterations"])


@pytest.mark.parametrize("precision", ["fp32", "fp64"])
def test_counting_copy_with_the_crossing_treatment_is_the_kernels_solve(precision: str) -> None:
    """With the ``mean`` treatment the script counts the second solves the kernels take on the steps whose slip
    changes sign: the velocity equals friction_substep's with crossing 1 bit for bit, the patches with a second solve
    are those whose point solve crossed, and those without one keep the point treatment's velocity."""
    patch = _patches()
    h = 2.5e-7
    point = fsi.count(patch, PAD, h, precision, zero_slip=False)
    mean = fsi.count(patch, PAD, h, precision, zero_slip=False, crossing=True)
    np.testing.assert_array_equal(mean["v"], _kernels_substep(patch, h, precision, 1))
    np.testing.assert_array_equal(mean["iterations"], point["iterations"])
    slip = patch["disc_speed"] - patch["v"]
    took = mean["segment_iterations"] > 0
    assert took.sum() >= 20 and np.all(np.sign(slip[took]) != np.sign(patch["disc_speed"][took] - point["v"][took]))
    np.testing.assert_array_equal(mean["v"][~took], point["v"][~took])
    assert not mean["segment_bisections"][~took].any()
    assert not np.array_equal(mean["v"][took], point["v"][took])


def test_command_writes_its_table(tmp_path: Path) -> None:
    """Two times of a short hf1 run: one row per time and solve in the JSON and the Markdown table."""
    out = tmp_path / "si"
    assert (
        fsi.main(["--scene", "hf1", "--dt", "5e-8", "--times", "1e-6", "2e-6", "--zero-slip", "--out", str(out)]) == 0
    )
    doc = json.loads((out / "solve_iterations.json").read_text())
    assert [(r["time_s"], r["variant"]) for r in doc["rows"]] == [
        (1e-6, "kernel"), (1e-6, "zero-slip"), (2e-6, "kernel"), (2e-6, "zero-slip")
    ]  # fmt: skip
    assert all(r["max"] >= r["p99"] >= 1 and sum(r["histogram"].values()) == doc["patches"] for r in doc["rows"])
    assert all(r["long_through_zero"] <= r["long"] for r in doc["rows"])
    # a warp waits for its slowest patch: the warps' largest counts average between the mean and the largest
    assert all(r["mean"] <= r["warp_max_mean"] <= r["max"] for r in doc["rows"])
    # hf1 slides at its start: every solve takes one Newton step and one evaluation to confirm it
    assert doc["rows"][0]["histogram"] == {"2": doc["patches"]}
    assert (out / "solve_iterations.md").read_text().count("\n| 1e-06 |") == 2


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--times", "2e-6", "1e-6"], "--times must increase"),
        (["--scene", "nope", "--times", "1e-6"], "nope"),
        (["--scene", "hf1", "--times", "1.5e-6"], "not a whole number of sample intervals"),
        (["--scene", "varying_area", "--times", "2e-6"], "growth spacing"),
        (["--scene", "hf1", "--dt", "3e-7", "--times", "1e-6"], "must divide the scene's sample interval"),
    ],
)
def test_refusals(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], words: str) -> None:
    """Bad input ends in one line naming it (exit 2), before any run."""
    with pytest.raises(SystemExit) as exc:
        fsi.main([*argv, "--out", str(tmp_path / "o")])
    assert exc.value.code == 2 and words in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_summary_takes_each_warps_slowest_patch() -> None:
    """Two warps of 32 patches and a last one of 3, counted from patch 0: groups starting one patch later
    (14/3) or counted from the end (19/3) give other means than the warps' 5, 8 and 4."""
    its = np.full(67, 2, dtype=np.int32)
    its[[0, 33, 63, 66]] = [5, 8, 6, 4]
    row = fsi.summary(its, np.zeros_like(its), np.zeros(len(its), dtype=bool))
    assert row["warp_max_mean"] == pytest.approx(17 / 3)
    assert row["max"] == 8 and row["histogram"] == {2: 63, 4: 1, 5: 1, 6: 1, 8: 1}
