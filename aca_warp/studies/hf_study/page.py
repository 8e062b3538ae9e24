"""The study's outputs: ``results.md`` (settings, the preset table, the sweep, the claims, figures, notes),
``study.json`` beside it, and the archive of both with the figures."""

from __future__ import annotations

import tarfile
from pathlib import Path
from typing import Any

from aca_warp.studies.hf_study.base import MM2, PAPER, PRESET_NAMES, SPREAD
from aca_warp.studies.hf_study.claims import comparisons
from aca_warp.studies.report import Log, clean, fmt, fmt_hz, md_table, write_json


def yes_no(v: Any) -> str:
    """A claim's result in bold, or that it was not measured."""
    return "not measured" if v is None else ("**yes**" if v else "**no**")


def _reused_note(study: dict[str, Any]) -> str:
    runs = [p["run"] for p in study["presets"].values()] + [
        p["run"] for p in (study.get("sweep") or {}).get("points", [])
    ]
    reused = sum(bool(r.get("reused")) for r in runs)
    if not reused:
        return ""
    return f" ({reused} of {len(runs)} runs reused from earlier run files (--reuse), with those runs' simulation times)"


def _header_lines(study: dict[str, Any]) -> list[str]:
    """Title, the command, device, versions, run and analysis settings, wall time."""
    s, m, v = study["settings"], study["machine"], study["versions"]
    return [
        "# HF study: stand-alone HF simulations (paper §3.1) and patch-area sweep",
        "",
        "One run per preset from rest (4 ms by default): the record ends in the linear growth phase of the "
        "friction instability and each verdict below rests on one realisation. The "
        "verdicts on the paper's statements are those of [validation.md](../validation.md) (seed ensembles of "
        "saturated runs); this page is the single-run record they are compared with.",
        "",
        f"Produced by `{study['command']}` on {study['created']}"
        + ("" if study["complete"] else " — **incomplete: the study did not finish**")
        + ".",
        "",
        f"* Device: {m['device_name']} (`{m['device']}`); host {m['host']}.",
        f"* Versions: Warp {v['warp-lang']}, aca-warp {v.get('aca-warp', '?')}, Python {v['python']}.",
        f"* Runs: {s['integrator']}, dt = {s['dt_s']:g} s, {s['precision']}; {s['duration_s']:g} s simulated per run "
        f"({s['steps_per_run']:,} steps) from rest; global outputs every {s['sample_dt_s']:g} s; per-patch velocities "
        f"every {s['patch_sample_dt_s']:g} s from {s['transient_s']:g} s to the end "
        f"({s['patch_record_s']:g} s, Δf = {s['patch_resolution_hz'] / 1e3:.3g} kHz).",
        f"* Analysis: `analyze_run`, band {s['band_hz'][0] / 1e3:g}–{s['band_hz'][1] / 1e3:g} kHz, Φ rule "
        f"`{s['rule']}`; S statistics over the bins with Φ ≥ {s['phi_min']}. First velocity peak: largest peak of "
        "the mean per-patch velocity amplitude spectrum (docs/analysis.md).",
        f"* Wall time of the whole study: {study['total_wall_s']:.0f} s" + _reused_note(study) + ".",
    ]


def _preset_table(study: dict[str, Any]) -> list[str]:
    """Presets HF1-HF4 side by side: scene, peaks (ours and the paper's), μ, S and Φ statistics, wall time."""
    pr = study["presets"]
    transient, phi = study["settings"]["transient_s"], study["settings"]["phi_min"]

    def row(label: str, fn: Any) -> list[str]:
        return [label, *(fn(pr[n]) if n in pr else "not run" for n in PRESET_NAMES)]

    rows = [
        row("patches, mean area", lambda p: f"{p['scene']['patches']}, {p['scene']['mean_area_m2'] / MM2:.3g} mm²"),
        row("M, F_N", lambda p: f"{p['scene']['M']:g}, {p['scene']['normal_force_N']:.1f} N"),
        row("matrix load share", lambda p: fmt(p.get("matrix_load_share"), ".2%")),
        row("first velocity peak (ours)", lambda p: fmt_hz(p.get("first_velocity_peak_hz"))),
        ["first velocity peak (paper)", *(fmt_hz(PAPER["first_velocity_peak_hz"][n]) for n in PRESET_NAMES)],
        row("isolated patch at mean area", lambda p: fmt_hz(p["scene"]["isolated_patch_hz_at_mean_area"])),
        row("first peak amplitude [m/s]", lambda p: fmt(p.get("first_velocity_peak_amplitude"))),
        row("Σu̇ peak", lambda p: fmt_hz(p.get("sum_velocity_peak_hz"))),
        row(
            "largest μ peak (amplitude / mean μ)",
            lambda p: f"{fmt_hz(p.get('mu_peak_hz'))} ({fmt(p.get('mu_peak_amplitude'))})",
        ),
        row(f"mean μ (t ≥ {transient:g} s)", lambda p: fmt(p.get("mu_mean"), ".4f")),
        row(
            f"median / max S (Φ ≥ {phi})", lambda p: f"{fmt(p.get('S_median_phi_min'))} / {fmt(p.get('S_max_phi_min'))}"
        ),
        row(
            f"bins with Φ ≥ {phi} (of those with S defined)",
            lambda p: f"{fmt(p.get('S_bins_phi_min'))} ({fmt(p.get('S_bins_defined'))})",
        ),
        row(
            f"median Φ (Φ ≥ {phi}), max Φ",
            lambda p: f"{fmt(p.get('Phi_median_phi_min'), '.0f')}, {fmt(p.get('Phi_max'))}",
        ),
        row("bins with S > S_null (all, Φ ≥ 2)", lambda p: fmt(p.get("S_bins_above_null"))),
        row(
            f"median S − S_null, fraction S > S_null (Φ ≥ {phi})",
            lambda p: f"{fmt(p.get('S_excess_median_phi_min'))}, {fmt(p.get('S_above_null_fraction_phi_min'), '.2f')}",
        ),
        row(f"median R_w (Φ ≥ {phi})", lambda p: fmt(p.get("R_w_median_phi_min"))),
        row("S, Φ at the first peak", lambda p: f"{fmt(p.get('S_at_first_peak'))}, {fmt(p.get('Phi_at_first_peak'))}"),
        row("simulation wall time [s]", lambda p: fmt(p["run"].get("wall_s"), ".1f")),
    ]
    return ["## Presets HF1–HF4", "", *md_table(["", *PRESET_NAMES], rows)]


def _fit_sentence(study: dict[str, Any]) -> str:
    """The fitted exponent with its standard error and interval, beside the paper's."""
    fit = study["sweep"]["fit"]
    if fit.get("exponent") is None:
        return "No exponent: fewer than two sweep points with a peak."
    se, ci = fit.get("stderr"), fit.get("ci95")
    spread = (
        f" ± {se:.2g} (1 s.e.; 95 % interval {ci[0]:.3f} to {ci[1]:.3f})"
        if se is not None
        else " (two points: no standard error)"
    )
    return (
        f"Fitted exponent of f against mean patch area: **{fit['exponent']:.3f}**{spread}, {fit['n_points']} points. "
        "Paper: −1/4 (isolated-patch estimate); its two reported peaks (73 kHz at 0.05 mm², 32.8 kHz at 1.25 mm²) "
        f"imply {study['paper']['exponent_from_peaks']:.3f}."
    )


def _sweep_section(study: dict[str, Any]) -> list[str]:
    """The area sweep: one row per point, the fitted exponent and the figure."""
    s, sw = study["settings"], study.get("sweep")
    if not sw:
        return ["## Area sweep", "", "Not run (`--skip-sweep`)."]
    rows = []
    for p in sw["points"]:
        f1, fi = p.get("first_velocity_peak_hz"), p["isolated_patch_hz_at_mean_area"]
        rows.append(
            [
                f"{p['mean_area_m2'] / MM2:.3g} mm²",
                f"{p['area_min_m2'] / MM2:.3g}–{p['area_max_m2'] / MM2:.3g} mm²",
                f"{p['normal_force_N']:.1f} N",
                fmt(p.get("matrix_load_share"), ".2%"),
                fmt_hz(f1),
                fmt_hz(fi),
                "–" if f1 is None else f"{f1 / fi:.3f}",
            ]
        )
    header = ["mean area", "areas", "F_N", "matrix load share", "first velocity peak", "isolated patch", "ratio"]
    return [
        "## Area sweep",
        "",
        f"{s['sweep_patches']} patches, areas uniform in [{SPREAD[0]}, {SPREAD[1]}] × mean, M = {s['sweep_M']:g}, "
        f"{s['sweep_speed_m_s']:g} m/s, F_N = {s['sweep_pressure_Pa'] / 1e6:.3g} MPa × total nominal patch area "
        "(all patches loaded; the matrix share shows whether the matrix touches the disc).",
        "",
        *md_table(header, rows),
        "",
        _fit_sentence(study),
        "",
        "![area sweep](area_sweep.png)",
        "",
        "[area_sweep.png](area_sweep.png), [area_sweep.pdf](area_sweep.pdf)",
    ]


def _claims_section(study: dict[str, Any]) -> list[str]:
    """The paper's statements, each with the measured verdict (and the metrics that disagree with it)."""
    rows = []
    for c in study["comparisons"]:
        verdict = yes_no(c["result"])
        others = [f"{k}: {'yes' if v else 'no'}" for k, v in (c.get("checks") or {}).items() if v is not None]
        if others and any(v != c["result"] for v in c["checks"].values() if v is not None):
            verdict += " (metrics disagree — " + "; ".join(others) + ")"
        rows.append([c["claim"], verdict, c["numbers"]])
    return ["## The paper's statements, measured", "", *md_table(["statement", "measured", "numbers"], rows)]


def _figures_section(study: dict[str, Any]) -> list[str]:
    """Links to every figure of the presets and the sweep."""
    lines = ["## Figures", ""]
    for n in PRESET_NAMES:
        files = [f for f in study["presets"].get(n, {}).get("figures", []) if not f.endswith(".pdf")]
        if files:
            names = {
                f: Path(f).stem.removeprefix(n + "_") + (" animation" if f.endswith(".gif") else "") for f in files
            }
            links = ", ".join(f"[{label}]({f})" for f, label in names.items())
            lines.append(f"* {n}: {links} (PDFs beside the PNGs)")
    if study.get("sweep"):
        lines.append("* area sweep: [area_sweep.png](area_sweep.png), [area_sweep.pdf](area_sweep.pdf)")
    if len(lines) == 2:
        lines.append("None written.")
    return lines


def write_markdown(study: dict[str, Any], path: Path) -> None:
    """``results.md`` of a (cleaned) study: settings, the preset table, the sweep, the claims, figures, notes."""
    s = study["settings"]
    notes = [
        "## Notes",
        "",
        "* Every run starts from rest (u = u̇ = 0); the per-patch spectra and S(f) leave out t < "
        f"{s['transient_s']:g} s. The global-output spectra (μ peak) cover the whole record.",
        "* The paper's peaks are read off its Fig. 8; its run lengths are not stated. Frequencies here are resolved to "
        f"Δf = {s['patch_resolution_hz'] / 1e3:.3g} kHz (Gaussian interpolation of the peak bin).",
        "* S > S_null: S above the mean S of Φ uniformly random phases (Monte-Carlo null level, docs/analysis.md).",
    ]
    sections = [_header_lines, _preset_table, _sweep_section, _claims_section, _figures_section]
    lines: list[str] = []
    for section in sections:
        lines += [*section(study), ""]
    path.write_text("\n".join(lines + notes) + "\n")


def write_outputs(study: dict[str, Any], outdir: Path, log: Log) -> None:
    """``study.json`` and ``results.md`` as the study stands now (with its claims and wall time)."""
    study["total_wall_s"] = log.elapsed()
    study["comparisons"] = comparisons(study)
    write_json(outdir / "study.json", clean(study), indent=2)
    write_markdown(clean(study), outdir / "results.md")


def write_archive(outdir: Path, target: Path, max_mib: float, log: Log) -> list[Path]:
    """Everything in ``outdir`` but run files, as one .tar.gz or, above ``max_mib`` of input, several parts.

    Files are packed in order into parts of at most ``max_mib`` uncompressed (a larger single file gets a part of
    its own), so every part stays below the limit; study.json and results.md go into the first part.
    """
    target.parent.mkdir(parents=True, exist_ok=True)
    skip = {target.resolve()}
    files = [p for p in sorted(outdir.rglob("*")) if p.is_file() and p.suffix != ".h5" and p.resolve() not in skip]
    files = [p for p in files if p.name in ("study.json", "results.md")] + [
        p for p in files if p.name not in ("study.json", "results.md") and not p.name.endswith(".tar.gz")
    ]
    limit = max_mib * 2**20
    parts: list[list[Path]] = [[]]
    size = 0
    for p in files:
        n = p.stat().st_size
        if parts[-1] and size + n > limit:
            parts.append([])
            size = 0
        parts[-1].append(p)
        size += n
    name = target.name.removesuffix(".tar.gz").removesuffix(".tgz")
    paths = [target] if len(parts) == 1 else [target.with_name(f"{name}-part{i + 1}.tar.gz") for i in range(len(parts))]
    for path, group in zip(paths, parts, strict=True):
        with tarfile.open(path, "w:gz") as tar:
            for p in group:
                tar.add(p, arcname=str(Path(outdir.name) / p.relative_to(outdir)))
        log(f"archive {path} ({path.stat().st_size / 2**20:.1f} MiB, {len(group)} files)")
    return paths
