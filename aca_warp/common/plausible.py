"""Plausibility of scene values: numbers far outside the physical range of a brake pad are refused, with the
likely unit mistake named (docs/scenes.md "Plausible ranges").

Every value of a scene is SI. A pad radius of 100 (millimetres typed for metres) or a patch area of 0.05 (mm²
for m²) is valid to the model, which then simulates a 200 m pad or patches the size of a table for hours; these
checks refuse such values before anything runs. The ranges are wide (a factor of 10 to 1000 beyond any brake
pad, the paper's scenes and the extreme scenes of docs/stability.md): a value outside them is a typing or unit
mistake far more often than an intended experiment. A scene that means it sets ``[scene] allow_implausible =
true`` (``Scene(allow_implausible=True)``; ``aca-warp hf/lf --allow-implausible`` sets it for one run), which is
stored with the scene in the run file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from aca_warp.common.errors import SceneError, option


class ImplausibleError(SceneError):
    """A scene value far outside the physical range of a brake pad (a likely unit mistake); exit 2."""


@dataclass(frozen=True)
class Range:
    """The plausible range of one kind of quantity, and the unit mistakes that lead out of it.

    Attributes:
        unit: SI unit of the values (empty for a dimensionless quantity).
        low: Smallest plausible magnitude (0: none; 0 itself is left to the validation).
        high: Largest plausible magnitude.
        why: What the range is, in words (for the message).
        typical: Magnitudes of real scenes [low, high]: a guessed unit counts when it lands here.
        above: Units a value above ``high`` may have been given in: (name, its value in the SI unit).
        below: Units a value below ``low`` may have been given in, or a text to show instead.
    """

    unit: str
    low: float
    high: float
    why: str
    typical: tuple[float, float]
    above: tuple[tuple[str, float], ...] = ()
    below: tuple[tuple[str, float], ...] | str = ()

    def guess(self, v: float, units: tuple[tuple[str, float], ...] | str) -> str:
        """'did you give mm? 100 mm = 0.1 m' for every unit of ``units`` that turns ``v`` into a typical value."""
        if isinstance(units, str):
            return units
        fits = [(name, v * f) for name, f in units if self.typical[0] <= v * f <= self.typical[1]]
        if not fits:
            return "check the unit and the exponent"
        names = " or ".join(name for name, _ in fits)
        return f"did you mean {names}? (" + ", ".join(f"{v:g} {name} = {self.of(si, '.3g')}" for name, si in fits) + ")"

    def of(self, v: float, spec: str = "g") -> str:
        """``v`` with its unit, as a message writes it (a dimensionless quantity bare)."""
        return f"{v:{spec}} {self.unit}" if self.unit else f"{v:{spec}}"


RANGES: dict[str, Range] = {
    "length": Range("m", 0.0, 2.0, "no brake pad is larger than 2 m", (5e-3, 0.5), (("mm", 1e-3), ("cm", 1e-2))),
    "height": Range(
        "m", 0.0, 1.0e-3, "patch heights are micrometres, 3 µm in the presets", (1e-8, 1e-4),
        (("µm", 1e-6), ("mm", 1e-3)),
    ),
    "area": Range(
        "m²", 1.0e-12, 1.0e-3, "contact patches are 1 µm² to 10 cm², 2e-8 to 2e-6 m² in the presets", (1e-11, 1e-4),
        (("mm²", 1e-6), ("µm²", 1e-12)), "did you convert mm² to m² twice (a factor 1e-12 instead of 1e-6)?",
    ),
    "force": Range(
        "N", 0.0, 1.0e6, "a brake pad's clamp force is 1e2 to 1e5 N, 487 N and 12.4 kN in the presets", (1e-2, 1e5),
        (("mN", 1e-3),),
    ),
    "pressure_bar": Range(
        "bar", 0.0, 1.0e3, "brake line pressures are 1 to 200 bar", (0.1, 200.0), (("Pa", 1e-5), ("kPa", 1e-2)),
    ),
    "speed": Range(
        "m/s", 0.0, 200.0, "disc surface speeds stay below 200 m/s, 10 m/s in the presets", (1e-4, 100.0),
        (("km/h", 1 / 3.6), ("mm/s", 1e-3)),
    ),
    "stiffness": Range(
        "N/m²", 1.0e5, 1.0e13, "the stiffness constants of Eqs. 1-3 are about 1e9 N/m², K_N = 2.39e9 in the presets",
        (1e7, 1e12), (), (("GPa", 1e9), ("MPa", 1e6)),
    ),
    "friction": Range(
        "", 0.0, 5.0, "dry friction coefficients are 0.1 to 1.5, a brake pad's about 0.4; Eq. 4's M, which bounds a "
        "patch's μ, is 0.8 and 0.4 in the presets, the matrix's μ 0.3", (1e-3, 2.0), (("%", 1e-2),),
    ),
    "hf_duration": Range(
        "s", 0.0, 1.0, "HF runs last milliseconds, the longest study 0.36 s", (1e-6, 0.5), (("ms", 1e-3), ("µs", 1e-6)),
    ),
    "sample_dt": Range(
        "s", 1.0e-10, 1.0e-3, "HF samples are microseconds apart, 1 MHz resolving the paper's 10-100 kHz lines",
        (1e-9, 1e-4), (("µs", 1e-6), ("ms", 1e-3), ("ns", 1e-9)), "check the exponent",
    ),
    "hf_step": Range(
        "s", 1.0e-13, 1.0e-5, "HF steps are nanoseconds, 5e-8 to 3.3e-7 s for strang by default", (1e-11, 1e-6),
        (("ns", 1e-9), ("µs", 1e-6)), "check the exponent",
    ),
    "lf_step": Range(
        "s", 1.0e-5, 1.0, "the LF step is 0.01 s, paper §2.1.3", (1e-4, 0.1), (("ms", 1e-3),),
        "the LF rules are calibrated for 0.01 s steps; HF steps belong to aca-warp hf",
    ),
    "lf_duration": Range(
        "s", 0.0, 1.0e4, "brake applications last seconds to minutes, 10 s in the paper", (1e-2, 3600.0),
        (("ms", 1e-3),),
    ),
    "lf_cell": Range(
        "m", 0.0, 2.0e-2, "LF cells and neighbourhood margins are about a millimetre, 1e-3 and 5e-4 m in the presets",
        (1e-5, 1e-2), (("mm", 1e-3), ("µm", 1e-6)),
    ),
    "thermal_length": Range(
        "m", 0.0, 0.1, "disc cheeks and thermal depths are micrometres to centimetres, 3e-5 to 0.02 m in the presets",
        (1e-7, 0.05), (("mm", 1e-3), ("µm", 1e-6)),
    ),
    "temperature": Range(
        "K", 150.0, 5000.0, "brake temperatures are 200 to 1500 K, 293.15 to 973.15 K in the presets; cast iron "
        "melts near 1450 K", (200.0, 2000.0), (), "did you mean °C? (temperatures are kelvin: K = °C + 273.15)",
    ),
    "temperature_scale": Range(
        "K", 1.0e-2, 1.0e4, "temperature scales are kelvin, 30 K in the presets", (0.1, 1000.0), (),
        "check the exponent",
    ),
    "density": Range(
        "kg/m³", 100.0, 3.0e4, "pad, disc and debris densities are 1000 to 8000 kg/m³, 2500 to 7200 in the presets",
        (300.0, 2.5e4), (), (("g/cm³", 1e3),),
    ),
    "heat_capacity": Range(
        "J/(kg K)", 10.0, 2.0e4, "specific heats of solids are 100 to 2000 J/(kg K), 460 and 1000 in the presets",
        (50.0, 5000.0), (), (("kJ/(kg K)", 1e3),),
    ),
    "conductivity": Range(
        "W/(m K)", 1.0e-2, 5.0e3, "thermal conductivities of solids are 0.1 to 400 W/(m K), 1 and 50 in the presets",
        (1e-2, 2000.0), (("mW/(m K)", 1e-3),), (("W/(cm K)", 1e2),),
    ),
    "heat_transfer": Range(
        "W/(m² K)", 0.1, 1.0e7, "convection and contact conductances are 5 to 1e5 W/(m² K), 100 and 1e4 in the presets",
        (1.0, 1e6), (), (("kW/(m² K)", 1e3),),
    ),
    "expansion": Range(
        "1/K", 1.0e-8, 1.0e-3, "expansion coefficients of solids are 1e-6 to 1e-4 1/K, 1.2e-5 in the presets",
        (1e-7, 5e-4), (("µm/(m K)", 1e-6),), "check the exponent",
    ),
    "wear": Range(
        "m³/J", 1.0e-21, 1.0e-9, "energy wear coefficients are 1e-16 to 1e-12 m³/J, 1e-15 to 2e-13 in the presets",
        (1e-19, 1e-10), (("mm³/(N m)", 1e-9),),
        "did you convert mm³/(N m) to m³/J twice (a factor 1e-18 instead of 1e-9)?",
    ),
    "pressure": Range(
        "Pa", 1.0e3, 1.0e9, "pressures under a brake pad are 1e4 to 1e7 Pa, 3e5 Pa in the presets", (1e3, 1e8), (),
        (("kPa", 1e3), ("bar", 1e5), ("MPa", 1e6)),
    ),
    "rate": Range(
        "1/s", 0.0, 1.0e3, "hazard rates are per second for patch lifetimes of seconds, 0.1 1/s in the presets",
        (1e-6, 100.0),
    ),
    "newton_per_bar": Range(
        "N/bar", 1.0, 1.0e5, "a caliper gives 100 to 10000 N of clamp force per bar, 370 N/bar in the presets",
        (10.0, 2e4), (), (("kN/bar", 1e3), ("N/Pa", 1e5)),
    ),
    "winkler": Range(
        "N/m³", 1.0e7, 1.0e16, "a pad matrix's Winkler stiffness E/H is 1e9 to 1e14 N/m³, 1.85e11 in the presets",
        (1e8, 1e15), (), (("N/mm³", 1e9), ("MPa/m", 1e6)),
    ),
}  # fmt: skip


def check(name: str, value: float, kind: str, *, allow: bool = False) -> None:
    """Refuse ``value`` of the quantity ``name`` when it lies outside the plausible range of ``kind``
    (:data:`RANGES`) and ``allow`` is False: :class:`ImplausibleError` naming the range and the likely mistake.
    Non-finite values and 0 are left to the validation that follows (they have their own messages)."""
    if allow:
        return
    r = RANGES[kind]
    v = abs(float(value))
    if not math.isfinite(v) or v == 0.0:
        return
    if v > r.high:
        where, hint = f"beyond {r.of(r.high)}", r.guess(v, r.above)
    elif v < r.low:
        where, hint = f"below {r.of(r.low)}", r.guess(v, r.below)
    else:
        return
    run_anyway = option(
        "set [scene] allow_implausible = true or pass allow_implausible=True to the scene or its loader",
        "set [scene] allow_implausible = true or pass --allow-implausible",
        "set allow_implausible = true in the spec's [base.scene] table",
    )
    raise ImplausibleError(f"{name} = {r.of(value)} — {where} ({r.why}); {hint}; to run it anyway {run_anyway}")


def flag(value: object, name: str = "scene.allow_implausible") -> bool:
    """The value of ``allow_implausible`` as a bool (SceneError for anything but true/false)."""
    if not isinstance(value, bool):
        raise SceneError(f"{name} must be true or false, got {value!r}")
    return value
