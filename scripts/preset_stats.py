#!/usr/bin/env python3
"""Per-preset statistics of the HF presets: patches, heights, contact, pressures and linear growth rates.

For every preset of ``aca_warp.scene.PRESETS`` (and, for a growing preset, once more at the areas that Eq. 10
reaches at the end of its run) this prints a markdown table of

* the patch count and the area range [mm²];
* the free heights h_i (min / median / max) [µm];
* the contact solve: the disc surface gap g above the matrix [µm], the patches in contact, the share of the load
  on the matrix, and the load relative to the two ends of the window in which every patch touches and the matrix
  does not, F_N / F_all (≥ 1: all in contact) and F_N / F_mat (≤ 1: matrix free) (``aca_warp.hf.contact.LoadWindow``);
* the patch pressures p_i = F_N,i / A_i (min / median / max) [MPa];
* the linear growth rate of each patch as an isolated oscillator at steady sliding,
  σ_i = (F_N,i·(−f′(ω r_i)) − c_i) / (2 m_i) [1/s], f the signed Eq. 4, c_i = 2ζ√(k_T,i m_i) (min / median / max;
  patches out of contact have σ_i = −c_i/(2 m_i) < 0).

``--derive MARGIN`` prints, for every preset with a height spread, the spread that puts the clamp force MARGIN
above the all-in-contact load (F_N = (1 + MARGIN) F_all): heights are h_0 + s z_i with z_i independent of s
(``PatchGenerator.heights``), so F_all = s Σ k_N,i (z_i − z_min) and s = F_N / ((1 + MARGIN) Σ k_N,i (z_i − z_min)),
rounded down to three significant figures.

Examples::

    python scripts/preset_stats.py                        # the table on stdout
    python scripts/preset_stats.py --out /tmp/presets.md  # and into a file
    python scripts/preset_stats.py --derive 0.10          # the height spreads of the paper presets
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import platform
import sys
from pathlib import Path

import numpy as np

from aca_warp.common.argtypes import nonneg
from aca_warp.common.errors import AcaError
from aca_warp.common.files import check_output_path, host_cpu
from aca_warp.hf.contact import load_window, solve_scene_contact
from aca_warp.scene import PRESETS, PatchGenerator, Scene, preset

HEADER = (
    "| preset | patches | A [mm²] | h [µm] min / med / max | g [µm] | in contact | matrix share | F_N / F_all "
    "| F_N / F_mat | p_i [MPa] min / med / max | σ_i [1/s] min / med / max |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|"
)


def grown_area(scene: Scene) -> np.ndarray:
    """Patch areas [m²] after the run's growth events, shape (n,): A ← A + increment·√A, ⌊duration/interval⌋ times."""
    a = scene.patches.area.copy()
    if scene.growth is None:
        return a
    tmp = np.empty_like(a)
    for _ in range(int(scene.duration / scene.growth.interval)):
        np.sqrt(a, out=tmp)
        tmp *= scene.growth.increment
        a += tmp
    return a


def growth_rate(scene: Scene, normal_force: np.ndarray, area: np.ndarray) -> np.ndarray:
    """σ_i = (F_N,i·(−f′(ω r_i)) − c_i) / (2 m_i) [1/s], shape (n,): isolated patch, linearised about u̇ = 0."""
    mat = scene.material
    m = mat.mass_per_area * area
    c = 2.0 * mat.damping_ratio * np.sqrt(mat.K_T * np.sqrt(area) * m)
    slope = scene.friction.derivative(scene.angular_velocity * scene.patches.friction_radius)
    return (normal_force * -slope - c) / (2.0 * m)


def preset_stats(scene: Scene, area: np.ndarray | None = None) -> dict[str, float | int | tuple]:
    """The statistics of one scene (at patch areas ``area`` [m²] if given), SI units."""
    a = scene.patches.area if area is None else area
    sol = solve_scene_contact(scene, area=area)
    win = load_window(scene, area=area)
    f = sol.patch_force
    three = lambda x: (float(np.min(x)), float(np.median(x)), float(np.max(x)))  # noqa: E731
    return {
        "patches": scene.patches.count,
        "area": (float(a.min()), float(a.max())),
        "height": three(scene.patches.height),
        "gap": sol.gap,
        "in_contact": int(np.count_nonzero(f > 0.0)),
        "matrix_share": 1.0 - sol.patch_share if sol.total > 0 else 0.0,
        "all_in_contact_ratio": scene.normal_force / win.all_in_contact if win.all_in_contact > 0 else math.inf,
        "matrix_ratio": scene.normal_force / win.matrix_contact if win.matrix_contact > 0 else math.inf,
        "pressure": three(f / a),
        "growth_rate": three(growth_rate(scene, f, a)),
    }


def row(name: str, st: dict) -> str:
    """One markdown table row of :func:`preset_stats`."""
    tri = lambda x, s, fmt: " / ".join(format(v * s, fmt) for v in x)  # noqa: E731
    return (
        f"| {name} | {st['patches']} | {st['area'][0] * 1e6:.3g}–{st['area'][1] * 1e6:.3g} "
        f"| {tri(st['height'], 1e6, '.3f')} | {st['gap'] * 1e6:.3f} | {st['in_contact']} "
        f"| {st['matrix_share']:.3f} | {st['all_in_contact_ratio']:.3f} | {st['matrix_ratio']:.3f} "
        f"| {tri(st['pressure'], 1e-6, '.3g')} | {tri(st['growth_rate'], 1.0, '.4g')} |"
    )


def table(names: tuple[str, ...] = PRESETS) -> str:
    """The markdown table of every preset in ``names`` (growing presets also at the end of their growth)."""
    lines = [HEADER]
    for name in names:
        s = preset(name)
        lines.append(row(name, preset_stats(s)))
        if s.growth is not None:
            lines.append(row(f"{name} (end, {s.duration:g} s)", preset_stats(s, grown_area(s))))
    return "\n".join(lines)


def derive_spread(scene: Scene, margin: float) -> float:
    """The height spread [m] that puts the scene's load ``margin`` above its all-in-contact load (3 sig. figs, down).

    Valid for generated patches on a fresh matrix with every height above it (heights h_0 + s z_i, z_i drawn
    independently of s).
    """
    gen = PatchGenerator(**scene.origin["patches"])
    unit = dataclasses.replace(gen, height=gen.height_truncation + 1.0, height_spread=1.0).generate(scene.pad)
    z = unit.height - (gen.height_truncation + 1.0)
    s = scene.normal_force / ((1.0 + margin) * np.sum(scene.material.K_N * np.sqrt(unit.area) * (z - z.min())))
    e = math.floor(math.log10(s)) - 2
    return math.floor(s / 10.0**e) * 10.0**e


def host() -> str:
    """The CPU model and core count of this machine."""
    return f"{host_cpu()}, {platform.platform()}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--out", type=Path, help="also write the table (markdown) to this file")
    ap.add_argument(
        "--derive", type=nonneg, metavar="MARGIN", help="print the height spreads for this load margin (>= 0)"
    )
    args = ap.parse_args(argv)
    if args.out is not None:
        try:
            check_output_path(args.out, overwrite=True)
        except AcaError as e:
            ap.error(str(e))
    if args.derive is not None:
        for name in PRESETS:
            s = preset(name)
            gen = s.origin.get("patches", {})
            if gen.get("height_spread", 0.0) > 0.0 and s.growth is None:
                spread = derive_spread(s, args.derive)
                margin = load_window(s.replace(patches=_with_spread(s, spread))).margin(s.normal_force)
                law = gen.get("height_law", "normal")
                print(f"{name}: height_spread = {spread:.3g} m (law {law}): F_N = (1 + {margin:.4f}) F_all")
        return 0
    text = table()
    print(f"machine: {host()}\n")
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")
    return 0


def _with_spread(scene: Scene, spread: float):
    """The scene's generated patches with ``height_spread`` replaced."""
    gen = PatchGenerator(**{**scene.origin["patches"], "height_spread": spread})
    return gen.generate(scene.pad)


if __name__ == "__main__":
    sys.exit(main())
