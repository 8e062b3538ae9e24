"""Varying-area study (paper §3.2, Eq. 10): HF1 patches under the HF2 load grow until the load moves to them.

Runs the ``varying_area`` preset (areas grow by ΔA = 1e-9 m·√A every 0.202 µs of simulated time, the normal
forces are re-solved after every growth event, ~0.36 s), recording μ(t) and the other global sums every sample
and, every ``--chunk`` of simulated time, the total patch area, the patch and matrix shares of the load and the
mean area. The run can be split over several calls: each call continues from ``--resume STATE.npz`` (patch
displacements and velocities, every model array the growth kernels change, the clock and all samples so far)
and stops at ``--until`` or after ``--max-wall`` seconds of wall time, writing ``OUT/varying_area_state.npz``;
the call that reaches the end also writes ``OUT/varying_area.npz`` (the record). ``--report`` turns a record
into figures (μ(t), load shares, STFT, CWT; PNG + PDF) and the generated part of docs/results_varying_area.md.

``--quick`` (CPU) compresses the growth: the increment is multiplied by ``--speedup`` (100) and the duration
divided by it, so the areas follow the same path in 1/100 of the time (3.6 ms); its spectra are coarse, and the
report's marks at 10 ms of growth (the frame it reads, the windows of the μ spread) shrink by the same factor.

Examples::

    python scripts/varying_area.py --quick --out /tmp/va --report             # CPU, ~2-3 min
    python scripts/varying_area.py --device cuda:0 --out $OUT/va --max-wall 500          # first GPU call
    python scripts/varying_area.py --device cuda:0 --out $OUT/va --engine onchip          # growth in the on-chip kernel
    python scripts/varying_area.py --device cuda:0 --out $OUT/va --max-wall 500 --resume va/varying_area_state.npz
    python scripts/varying_area.py --report-only va/varying_area.npz                      # figures + docs

As a library: :class:`Segment` holds a run between calls (:meth:`Segment.advance`, :meth:`Segment.save`,
:meth:`Segment.load`); :func:`simulate` is one call, :func:`analyse` the numbers of a record, :func:`report` its
figures and docs section.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import nonneg, positive
from aca_warp.common.errors import AcaError, SceneError
from aca_warp.hf.model import PadModel
from aca_warp.hf.options import INTEGRATORS, steps_per_event
from aca_warp.hf.recorder import GLOBAL_NAMES
from aca_warp.hf.solver import GROWTH_MUTABLE, stable_step
from aca_warp.hf.state import HFState
from aca_warp.scene import Growth, Record, Scene, preset
from aca_warp.studies.hf_study.base import isolated_frequency
from aca_warp.studies.report import (
    add_device,
    add_page_options,
    figure,
    generated_markers,
    md_table,
    replace_generated,
    save_figure,
    write_json,
)
from aca_warp.studies.runs import model_at_rest, run_engine

STATE_FILE = "varying_area_state.npz"
RECORD_FILE = "varying_area.npz"
PAPER_PEAK_HZ = 69.1e3  # the largest STFT peak of the paper's Fig. 10
MARK_S = 0.01  # s of growth: the start of the falling line of the paper's Fig. 10, and the μ-spread window
BEGIN, END = generated_markers("scripts/varying_area.py --report")


STUDY_DT = 1.0e-8  # s: the step of the study's committed results (docs/results_varying_area.md)


def make_scene(speedup: float = 1.0, duration: float | None = None, base: Scene | None = None) -> Scene:
    """The ``varying_area`` preset (or ``base``) with growth ×``speedup`` and duration ÷``speedup``."""
    s = base or preset("varying_area")
    g = s.growth or Growth()
    return s.replace(
        growth=Growth(increment=g.increment * speedup, interval=g.interval),
        duration=(duration or s.duration) / speedup,
    )


def snapshot(model: PadModel) -> dict[str, float]:
    """Load shares and areas of the (single) pad now."""
    fn = model.host("normal_force").astype(np.float64)
    fm = float(model.host("pad_matrix_force")[0])
    area = model.host("area").astype(np.float64)
    load = model.scenes[0].normal_force
    return {
        "patch_force": float(fn.sum()),
        "matrix_force": fm,
        "patch_share": float(fn.sum() / load),
        "matrix_share": fm / load,
        "area_total": float(area.sum()),
        "area_mean": float(area.mean()),
        "patches_loaded": float((fn > 0).mean()),
    }


class Segment:
    """Simulation state between calls: model + state + clock + samples."""

    def __init__(self, scene: Scene, device: str, precision: str) -> None:
        self.scene = scene
        model, state = model_at_rest(scene, device, precision)
        self.model: PadModel = model
        self.state: HFState = state
        self.sim_time = 0.0
        self.steps = 0
        self.wall = 0.0
        self.time: list[np.ndarray] = []
        self.globals: list[np.ndarray] = []
        self.snaps: list[dict[str, float]] = [{"time": 0.0, **snapshot(self.model)}]

    def save(self, path: Path, meta: dict) -> None:
        """Write the state, the clock, all samples and ``meta`` (JSON) to the ``.npz`` file ``path``."""
        m = self.model
        u, v = self.state.numpy()
        arrays = {f"model_{k}": m.host(k) for k in GROWTH_MUTABLE}
        snaps = {f"snap_{k}": np.array([s[k] for s in self.snaps]) for k in self.snaps[0]}
        np.savez_compressed(
            path,
            u=u,
            v=v,
            sim_time=self.sim_time,
            steps=self.steps,
            wall=self.wall,
            time=np.concatenate(self.time) if self.time else np.zeros(0),
            globals=np.concatenate(self.globals) if self.globals else np.zeros((0, len(GLOBAL_NAMES))),
            meta=json.dumps(meta),
            **arrays,
            **snaps,
        )

    def load(self, path: Path) -> dict:
        """Continue from the file :meth:`save` wrote; returns its ``meta``."""
        d = np.load(path)
        m = self.model
        for k in GROWTH_MUTABLE:
            m.arrays[k].assign(d[f"model_{k}"])
        self.state.u.assign(d["u"])
        self.state.v.assign(d["v"])
        self.sim_time = float(d["sim_time"])
        self.steps = int(d["steps"])
        self.wall = float(d["wall"])
        self.time = [d["time"]]
        self.globals = [d["globals"]]
        keys = [k[5:] for k in d.files if k.startswith("snap_")]
        self.snaps = [dict(zip(keys, vals, strict=True)) for vals in zip(*(d[f"snap_{k}"] for k in keys), strict=True)]
        self.snaps = [{k: float(v) for k, v in s.items()} for s in self.snaps]
        return json.loads(str(d["meta"]))

    def advance(
        self,
        until: float,
        *,
        chunk: float,
        integrator: str,
        dt: float,
        max_wall: float,
        engine: str = "general",
        growth_dt: float | None = None,
    ) -> None:
        """Run in chunks of ``chunk`` simulated seconds to ``until`` or until ``max_wall`` wall seconds pass
        (``engine``: general, onchip or auto; ``growth_dt``: the growth events' spacing [s], None for the scene's
        interval; as :class:`aca_warp.hf.options.RunOptions`). Each chunk counts its growth events from its start."""
        rec = Record(sample_dt=self.scene.record.sample_dt)
        t_start = time.perf_counter()
        while self.sim_time < until - 0.5 * rec.sample_dt:
            d = min(chunk, until - self.sim_time)
            res = run_engine(
                self.model, self.state, engine=engine, duration=d, integrator=integrator, dt=dt, record=rec,
                growth_dt=growth_dt,
            )  # fmt: skip
            c = res.collect()
            if not res.complete:
                raise RuntimeError(f"run stopped at {self.sim_time + res.sim_time:.6g} s: {res.fault}")
            first = 0 if not self.time else 1  # sample 0 of a continuation repeats the previous last sample
            self.time.append(self.sim_time + c.time[first:])
            self.globals.append(c.globals[first:, 0, :])
            self.sim_time += res.sim_time
            self.steps += res.steps
            self.wall += res.wall_time
            self.snaps.append({"time": self.sim_time, **snapshot(self.model)})
            el = time.perf_counter() - t_start
            s = self.snaps[-1]
            print(
                f"t = {self.sim_time:.5g} s, μ = {c.globals[-1, 0, 0]:.4f}, patch share {s['patch_share']:.3f}, "
                f"mean area {s['area_mean'] * 1e6:.4f} mm², {res.steps / max(res.wall_time, 1e-9):.3g} steps/s, "
                f"wall {el:.0f} s",
                flush=True,
            )
            if el > max_wall:
                break


def _resume(seg: Segment, path: Path, meta: dict[str, Any]) -> None:
    """Load ``seg`` from the state file ``path``, which must have been made with the settings of ``meta``."""
    old = seg.load(path)
    for k in ("speedup", "duration", "integrator", "dt", "precision", "chunk", "growth_dt"):
        if old.get(k) != meta[k]:  # states made before growth_dt was recorded ran at the scene's interval (None)
            raise SystemExit(f"--resume: the state was made with {k} = {old.get(k)}, this call has {meta[k]}")
    meta["calls"] = old["calls"]


def simulate(args: argparse.Namespace) -> Path | None:
    """One call: fresh or resumed, to ``--until`` / ``--max-wall``; returns the record file when finished."""
    import warp as wp

    from aca_warp.common.files import machine

    speed = args.speedup if args.quick else 1.0
    scene = make_scene(speed, args.duration)
    seg = Segment(scene, args.device, args.precision)
    meta = {
        "speedup": speed,
        "duration": scene.duration,
        "integrator": args.integrator,
        "dt": args.dt,
        "precision": args.precision,
        "chunk": args.chunk,
        "growth_dt": args.growth_dt,
        "calls": [],
    }
    if args.resume:
        _resume(seg, Path(args.resume), meta)
    est = stable_step(seg.model)
    print(
        f"varying_area: {scene.patches.count} patches, duration {scene.duration:g} s, growth ×{speed:g}, "
        f"{args.integrator} dt {args.dt:g} s {args.precision} on {args.device}; from t = {seg.sim_time:.6g} s; "
        f"stable-step estimate now: springs {est.spring:.3g} s, friction {est.friction:.3g} s",
        flush=True,
    )
    until = min(scene.duration, args.until or scene.duration)
    w0 = seg.wall
    seg.advance(
        until, chunk=args.chunk, integrator=args.integrator, dt=args.dt, max_wall=args.max_wall, engine=args.engine,
        growth_dt=args.growth_dt,
    )  # fmt: skip
    call = {"machine": machine(wp.get_device(args.device)), "warp": wp.__version__, "sim_time": seg.sim_time}
    meta["calls"].append({**call, "wall_s": seg.wall - w0, "engine": args.engine})
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seg.save(out / STATE_FILE, meta)
    print(f"wrote {out / STATE_FILE} at t = {seg.sim_time:.6g} s of {scene.duration:g} s")
    if seg.sim_time >= scene.duration - 0.5 * scene.record.sample_dt:
        path = out / RECORD_FILE
        seg.save(path, {**meta, "complete": True, "steps": seg.steps, "wall_s": seg.wall})
        print(f"complete: wrote {path}")
        return path
    print("not finished: run again with --resume", out / STATE_FILE)
    return None


# ----------------------------------------------------------------------------------------------- analysis


def _stft_numbers(mu: np.ndarray, dt: float, mark: float) -> dict[str, Any]:
    """STFT of μ (sampled every ``dt`` [s]): dominant frequency ≥ 5 kHz per frame, the largest peaks (overall,
    in 60-80 kHz around the paper's 69.1 kHz, and in the first frame from ``mark`` [s])."""
    from aca_warp.analysis.report import default_stft_window
    from aca_warp.analysis.timefreq import stft

    st, sf, sa, sinfo = stft(mu, dt, window_s=default_stft_window(mu.size, dt), detrend="linear")
    band = sf >= 5e3  # dominant oscillation (above the slow trend)
    dom = sf[band][np.argmax(sa[band], axis=0)]
    k = np.unravel_index(np.argmax(sa[band]), sa[band].shape)
    paper = (sf >= 60e3) & (sf <= 80e3)  # the band of the paper's largest peak
    kp = np.unravel_index(np.argmax(sa[paper]), sa[paper].shape)
    first = min(int(np.searchsorted(st, mark)), st.size - 1)  # the first frame from the mark (or the last frame)
    kf = int(np.argmax(sa[band][:, first]))
    return {
        "stft": (st, sf, sa, sinfo),
        "dominant_stft": dom,
        "largest_stft_peak_hz": float(sf[band][k[0]]),
        "largest_stft_peak_time": float(st[k[1]]),
        "largest_stft_peak_amplitude": float(sa[band][k]),
        "band_60_80khz_peak": [float(sf[paper][kp[0]]), float(st[kp[1]]), float(sa[paper][kp])],
        "peak_at_10ms": [float(st[first]), float(sf[band][kf]), float(sa[band][kf, first])],
        "dominant_thirds_hz": [float(np.median(dom[i])) for i in np.array_split(np.arange(st.size), 3)],
    }


def _cwt_numbers(mu: np.ndarray, dt: float) -> dict[str, Any]:
    """Multirate CWT of μ − mean μ (sampled every ``dt`` [s]) and its dominant frequency ≥ 5 kHz over time."""
    from aca_warp.analysis.report import default_cwt_freqs, multirate_cwt

    freqs = default_cwt_freqs(mu.size, dt)
    stride = 1 << max(0, math.ceil(math.log2(max(1.0, mu.size / 2048))))
    ct, cf, ca, cinfo = multirate_cwt(mu - mu.mean(), dt, freqs, stride=stride)
    band = cf >= 5e3
    return {"cwt": (ct, cf, ca, cinfo), "dominant_cwt": cf[band][np.argmax(ca[band], axis=0)]}


def analyse(path: Path) -> dict:
    """STFT and CWT of μ(t), dominant frequencies over time and the trends the paper reports."""
    d = np.load(path)
    meta = json.loads(str(d["meta"]))
    t, g = d["time"], d["globals"]
    mu = g[:, 0]
    dt = float(np.median(np.diff(t)))
    mark = MARK_S / meta["speedup"]  # 10 ms of growth, compressed as the growth is
    window = max(1, round(mark / dt))
    snaps = {k[5:]: d[k] for k in d.files if k.startswith("snap_")}
    return {
        "meta": meta,
        "t": t,
        "globals": g,
        "dt": dt,
        "mark_s": mark,
        **_stft_numbers(mu, dt, mark),
        **_cwt_numbers(mu, dt),
        "mu_std_first_last_10ms": [float(mu[:window].std()), float(mu[-window:].std())],
        "snaps": snaps,
        "mu_thirds": [float(mu[i].mean()) for i in np.array_split(np.arange(mu.size), 3)],
        "isolated_hz_start_end": [
            isolated_frequency(float(snaps["area_mean"][0])),
            isolated_frequency(float(snaps["area_mean"][-1])),
        ],
    }


# ----------------------------------------------------------------------------------------------- report


def _figure_mu(a: dict, caption: str) -> Any:
    """μ(t) and its running mean."""
    t, mu = a["t"], a["globals"][:, 0]
    fig = figure(figsize=(9, 3.8))
    ax = fig.subplots()
    ax.plot(t, mu, lw=0.3, color="0.6", label="μ(t)", rasterized=mu.size > 5000)
    nb = max(1, mu.size // 400)
    ax.plot(
        t[: mu.size // nb * nb].reshape(-1, nb).mean(1),
        mu[: mu.size // nb * nb].reshape(-1, nb).mean(1),
        "C0",
        label=f"mean over {nb * a['dt'] * 1e3:.3g} ms",
    )
    ax.set_xlabel("time [s]")
    ax.set_ylabel("μ")
    ax.legend(fontsize=8)
    ax.set_title(f"Coefficient of friction, varying area. {caption}", fontsize=8)
    return fig


def _figure_load_share(a: dict, caption: str) -> Any:
    """Patch and matrix shares of the load and the mean patch area over time."""
    sn = a["snaps"]
    fig = figure(figsize=(9, 3.8))
    ax = fig.subplots()
    ax.plot(sn["time"], sn["patch_share"], "C1", label="patches")
    ax.plot(sn["time"], sn["matrix_share"], "C2", label="matrix")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("share of the normal load")
    ax2 = ax.twinx()
    ax2.plot(sn["time"], sn["area_mean"] * 1e6, "k:", label="mean patch area")
    ax2.set_ylabel("mean patch area [mm²]")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8)
    ax.set_title(f"Load shares (re-solved after every growth event). {caption}", fontsize=8)
    return fig


def _figure_map(a: dict, key: str, caption: str) -> Any:
    """The STFT (``key`` = stft) or CWT (cwt) amplitude of μ with the dominant frequency ≥ 5 kHz."""
    tt, ff, aa, info = a[key]
    fig = figure(figsize=(9, 4.5))
    ax = fig.subplots()
    keep = ff >= 1e3
    im = ax.pcolormesh(
        tt, ff[keep] / 1e3, np.log10(np.maximum(aa[keep], 1e-12)), shading="auto", cmap="magma", rasterized=True
    )
    ax.plot(tt, a[f"dominant_{key}"] / 1e3, "c.", ms=2, label="dominant f ≥ 5 kHz")
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("frequency [kHz]")
    fig.colorbar(im, ax=ax, label="log10 amplitude of μ")
    ax.legend(fontsize=8, loc="lower left")
    ax.set_title(f"{key.upper()} of μ(t): {info['caption'][:150]}\n{caption}", fontsize=7)
    return fig


def figures(a: dict, figdir: Path, caption: str) -> list[str]:
    """``va_mu``, ``va_load_share``, ``va_stft``, ``va_cwt`` (PNG + PDF) of the analysis ``a``; returns the stems."""
    made = {
        "va_mu": _figure_mu(a, caption),
        "va_load_share": _figure_load_share(a, caption),
        "va_stft": _figure_map(a, "stft", caption),
        "va_cwt": _figure_map(a, "cwt", caption),
    }
    for stem, fig in made.items():
        fig.tight_layout()
        save_figure(fig, figdir, stem)
    return list(made)


def caption_of(meta: dict[str, Any]) -> str:
    """Device, Warp, integrator, step, precision, engines and duration of a record's ``meta``."""
    call = meta["calls"][-1]
    q = f", growth ×{meta['speedup']:g} compressed (--quick)" if meta["speedup"] != 1 else ""
    engines = sorted({c.get("engine", "general") for c in meta["calls"]})
    return (
        f"{call['machine']['device_name']}; Warp {call['warp']}; {meta['integrator']} dt {meta['dt']:g} s "
        f"{meta['precision']}, {'/'.join(engines)} engine; {meta['duration']:g} s{q}"
    )


def _generated_lines(a: dict, caption: str, stems: list[str], figdir: Path) -> list[str]:
    """The docs section: run, μ and dominant frequency by thirds, load shares, peaks, spread, figures."""
    meta, sn = a["meta"], a["snaps"]
    big, band, mark = a["largest_stft_peak_amplitude"], a["band_60_80khz_peak"], a["peak_at_10ms"]
    std = a["mu_std_first_last_10ms"]
    lines = [
        "",
        f"Run: {caption}; {meta['steps']} steps in {meta['wall_s']:.0f} s of stepping over "
        f"{len(meta['calls'])} call(s).",
        "",
        *md_table(
            ["quantity", "first third", "middle third", "last third"],
            [
                ["mean μ", *(f"{x:.4f}" for x in a["mu_thirds"])],
                ["median dominant STFT frequency (≥ 5 kHz)", *(f"{x / 1e3:.1f} kHz" for x in a["dominant_thirds_hz"])],
            ],
        ),
        "",
        f"* Patch share of the load: {sn['patch_share'][0]:.3f} at the start → {sn['patch_share'][-1]:.3f} at the end "
        f"(matrix {sn['matrix_share'][0]:.3f} → {sn['matrix_share'][-1]:.3f}); mean patch area "
        f"{sn['area_mean'][0] * 1e6:.4f} → {sn['area_mean'][-1] * 1e6:.4f} mm².",
        f"* Largest STFT amplitude (f ≥ 5 kHz): {big:.3g} at {a['largest_stft_peak_hz'] / 1e3:.1f} kHz, "
        f"t = {a['largest_stft_peak_time']:.4g} s (paper Fig. 10: ≈ 0.004 at {PAPER_PEAK_HZ / 1e3:.1f} kHz). "
        f"Largest in 60–80 kHz: {band[2]:.3g} at {band[0] / 1e3:.1f} kHz, t = {band[1]:.4g} s. Largest at "
        f"t = {mark[0]:.4g} s: {mark[2]:.2g} at {mark[1] / 1e3:.1f} kHz.",
        f"* Standard deviation of μ over the first and the last {a['mark_s'] * 1e3:g} ms: {std[0]:.2g} and "
        f"{std[1]:.2g}.",
        f"* Isolated-patch frequency √(k_T/m)/2π at the mean area: {a['isolated_hz_start_end'][0] / 1e3:.1f} kHz → "
        f"{a['isolated_hz_start_end'][1] / 1e3:.1f} kHz.",
        f"* STFT: {a['stft'][3]['caption']}.",
        f"* CWT: {a['cwt'][3]['caption']}.",
        "",
    ]
    for s in stems:
        lines += [f"![{s}](figures/{figdir.name}/{s}.png)", ""]
    return lines


SUMMARY_KEYS = (
    "mu_thirds",
    "dominant_thirds_hz",
    "largest_stft_peak_hz",
    "largest_stft_peak_time",
    "largest_stft_peak_amplitude",
    "band_60_80khz_peak",
    "peak_at_10ms",
    "mu_std_first_last_10ms",
    "isolated_hz_start_end",
)
"""The numbers of :func:`analyse` that ``summary.json`` keeps."""


def report(path: Path, page: Path, figdir: Path) -> None:
    """Figures of the record ``path`` into ``figdir`` (with ``summary.json``) and the generated part of ``page``."""
    a = analyse(path)
    caption = caption_of(a["meta"])
    stems = figures(a, figdir, caption)
    replace_generated(page, _generated_lines(a, caption, stems, figdir), (BEGIN, END), "Varying-area study")
    summary = {k: a[k] for k in SUMMARY_KEYS}
    summary["patch_share"] = [float(a["snaps"]["patch_share"][0]), float(a["snaps"]["patch_share"][-1])]
    write_json(figdir / "summary.json", {"caption": caption, **summary})
    print(f"wrote {page}, figures in {figdir}: {json.dumps(summary)}")


# ----------------------------------------------------------------------------------------------- command line


def build_parser() -> argparse.ArgumentParser:
    """The command line of the study."""
    ap = argparse.ArgumentParser(
        description=__doc__.split("As a library:")[0].rstrip(), formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_device(ap)
    ap.add_argument("--quick", action="store_true", help="growth ×--speedup, duration ÷--speedup (CPU)")
    ap.add_argument("--speedup", type=positive, default=100.0, help="growth compression of --quick (default 100)")
    ap.add_argument("--duration", type=positive, help="simulated duration before --quick compression [s] (0.36)")
    ap.add_argument("--integrator", default="strang", choices=[i for i in INTEGRATORS if i != "adaptive"])
    ap.add_argument("--dt", type=positive, default=STUDY_DT, help=f"step [s] (default {STUDY_DT:g}, the results' step)")
    ap.add_argument("--precision", default="fp64", choices=["fp32", "fp64"])
    ap.add_argument(
        "--engine",
        default="general",
        choices=["general", "onchip", "auto"],
        help="HF engine (default general; onchip: growth inside the on-chip kernel, strang only; docs/onchip.md)",
    )
    ap.add_argument(
        "--growth-dt",
        type=positive,
        metavar="S",
        help="simulated time between growth events [s] (default: the scene's growth interval, the paper's clock; "
        "aca-warp hf --growth-dt, docs/model.md 2.10); a whole number of them must fit --chunk",
    )
    ap.add_argument("--chunk", type=positive, default=1e-3, help="simulated time per run_hf call / load snapshot [s]")
    ap.add_argument("--until", type=positive, help="stop this call at this simulated time [s]")
    ap.add_argument("--max-wall", type=nonneg, default=math.inf, help="stop this call after this wall time [s]")
    ap.add_argument("--resume", help="continue from this state file of a previous call")
    ap.add_argument("--out", default="varying_area_out", help="folder of the state and record files")
    ap.add_argument("--report", action="store_true", help="when finished, write figures and the docs page")
    ap.add_argument("--report-only", metavar="RECORD", help="only write figures and docs from a record file")
    add_page_options(ap, "docs/results_varying_area.md", "docs/figures/varying_area")
    return ap


def _check(args: argparse.Namespace) -> None:
    """Refuse, before anything runs or is written (AcaError): a --report-only record or --resume state that is not
    there, an absent device, an --out or page that cannot be written."""
    from aca_warp.common.devices import get_device
    from aca_warp.common.files import check_output_folder, check_output_path

    for option, path in (("--report-only", args.report_only), ("--resume", args.resume)):
        if path and not Path(path).is_file():
            raise SceneError(f"{option}: no file {path}")
    if args.growth_dt is not None:  # each chunk counts its events from its start: a remainder loses growth per chunk
        spacing = steps_per_event(args.growth_dt, args.dt) * args.dt  # the events' spacing in whole steps
        if abs(args.chunk / spacing - round(args.chunk / spacing)) > 1e-9:
            raise SceneError(
                f"--growth-dt {args.growth_dt:g} s (events every {spacing:g} s at --dt {args.dt:g} s) does not divide "
                f"--chunk {args.chunk:g} s: choose a spacing that does"
            )
    if args.report or args.report_only:
        check_output_path(args.page, overwrite=True)
        check_output_folder(args.figures)
    if not args.report_only:
        get_device(args.device)
        check_output_folder(args.out)


def main(argv: list[str] | None = None) -> int:
    """Run one call of the study (or only its report); returns 0."""
    from aca_warp.studies.report import init_warp

    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        _check(args)
    except AcaError as e:
        ap.error(str(e))
    if args.report_only:
        report(Path(args.report_only), Path(args.page), Path(args.figures))
        return 0
    init_warp()
    path = simulate(args)
    if path is not None and args.report:
        report(path, Path(args.page), Path(args.figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
