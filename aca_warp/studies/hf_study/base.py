"""The study's constants and the physics it compares with: the presets, the nominal patch count and the mean
patch pressure of hf1, the run lengths (full and ``--quick``), the paper's numbers and the tolerances of its
claims; the isolated-patch frequency (paper Eq. 2) and the power-law fit f = c A^b."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

PRESET_NAMES = ("hf1", "hf2", "hf3", "hf4")
NOMINAL_PATCHES = 1758
HF1_FORCE = 487.2  # N
HF1_MEAN_AREA = 5.0e-8  # m²
DEFAULT_PRESSURE = HF1_FORCE / (NOMINAL_PATCHES * HF1_MEAN_AREA)  # ≈ 5.54 MPa mean patch pressure of hf1
SPREAD = (0.4, 1.6)  # patch areas uniform in [0.4, 1.6] x mean (the paper's 0.02-0.08 and 0.5-2.0 mm²)
MM2 = 1.0e-6  # m² per mm²

FULL_DURATION, QUICK_DURATION = 4.0e-3, 2.0e-4  # s
FULL_TRANSIENT, QUICK_TRANSIENT = 2.0e-4, 5.0e-5  # s

PAPER = {
    "first_velocity_peak_hz": {"hf1": 73.0e3, "hf2": 32.8e3, "hf3": 73.0e3, "hf4": 32.8e3},
    "exponent": -0.25,
    "mean_area_m2": {"hf1": 5.0e-8, "hf2": 1.25e-6, "hf3": 5.0e-8, "hf4": 1.25e-6},
    "source": "Merlis & Ostermeyer 2019, §3.1, Figs. 8-9",
}
PEAK_TOLERANCE = 0.05  # relative, for "agrees with the paper's peak" (or two frequency bins, if larger)
EXPONENT_TOLERANCE = 0.025  # absolute (10 % of 1/4), for "agrees with -1/4" (or two standard errors, if larger)


def isolated_frequency(area: np.ndarray | float, material: Any = None) -> np.ndarray | float:
    """Natural frequency of an isolated patch sqrt(k_T / m) / 2 pi, k_T = K_T sqrt(A), m = rho_A A (paper Eq. 2)
    [Hz] of patch areas ``area`` [m², any shape]; ``material``: a ``Material`` (None: the default one)."""
    if material is None:
        from aca_warp.scene import Material

        material = Material()
    area = np.asarray(area, dtype=np.float64)
    f = np.sqrt(material.K_T * np.sqrt(area) / (material.mass_per_area * area)) / (2.0 * np.pi)
    return float(f) if f.ndim == 0 else f


def fit_power_law(area: np.ndarray, freq: np.ndarray) -> dict[str, Any]:
    """Least-squares fit of log f = log c + b log A; b, its standard error and 95 % interval (n > 2)."""
    ok = np.isfinite(area) & np.isfinite(freq) & (area > 0) & (freq > 0)
    x, y = np.log(np.asarray(area)[ok]), np.log(np.asarray(freq)[ok])
    n = int(x.size)
    out: dict[str, Any] = {"n_points": n, "exponent": None, "stderr": None, "ci95": None, "prefactor": None}
    if n < 2 or np.ptp(x) == 0:
        return out
    xm, ym = x.mean(), y.mean()
    sxx = float(np.sum((x - xm) ** 2))
    b = float(np.sum((x - xm) * (y - ym)) / sxx)
    a = float(ym - b * xm)
    out.update(exponent=b, prefactor=math.exp(a), prefactor_unit="Hz m^(-2b)")
    if n > 2:
        from scipy.stats import t as student_t

        resid = y - (a + b * x)
        se = math.sqrt(float(np.sum(resid**2)) / (n - 2) / sxx)
        half = float(student_t.ppf(0.975, n - 2)) * se
        out.update(stderr=se, ci95=[b - half, b + half], rms_residual_log=float(np.sqrt(np.mean(resid**2))))
    return out
