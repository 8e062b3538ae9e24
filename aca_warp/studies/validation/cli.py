"""The command line of the validation study (``scripts/validation.py``): the options, the listing, the dry run
(every batch planned and its cost estimated, nothing run), running the selected experiments in their batches
(reusing their checkpoints), writing the compact ``results.json`` and a log, and rendering the page's generated
section from that file (also alone: ``--report RESULTS --page PAGE``).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import int_at_least, nonneg, positive
from aca_warp.common.devices import get_device
from aca_warp.common.errors import AcaError, SceneError
from aca_warp.studies.report import Log, command_line, generated_markers, replace_generated, unsigned_zero
from aca_warp.studies.validation import multiscale as validation_multiscale
from aca_warp.studies.validation.base import (
    EXPERIMENTS,
    FULL,
    QUICK,
    ROWS,
    Config,
    Experiment,
    close_pools,
    same_settings,
)
from aca_warp.studies.validation.cost import Costs, batch_friction_step, overheads
from aca_warp.studies.validation.experiments import (
    Prepared,
    load_result,
    make_batch,
    prepare,
    reanalyse,
    run_batch,
    same_definition,
)
from aca_warp.studies.validation.results import render_report, write_results
from aca_warp.studies.validation.settings import STEPPING

MARKER = "scripts/validation.py"  # the generated section's marker on the page


def build_parser() -> argparse.ArgumentParser:
    """The command line (``scripts/validation.py``)."""
    p = argparse.ArgumentParser(
        prog="validation.py",
        description="Seed ensembles of HF runs against the paper's statements; writes the runs under --out, the "
        "compact results.json and a log under --results, and, with --page, the generated section of a docs page.",
        epilog="Full variant (GPU, one call): python3 scripts/validation.py --device cuda:0 --out DIR --results "
        "RESULTS --max-wall 500 (406 s on one H200). Quick CPU smoke check: --quick. The page from a results file "
        "alone: --report RESULTS/results.json --page docs/validation.md. Checkpoints: each experiment's result is "
        "saved under DIR/<experiment>/ when done and reused by a rerun with the same settings (--rerun: run again).",
    )
    p.add_argument("--out", type=Path, default=Path("out/validation"), help="folder of the runs (created)")
    p.add_argument("--results", type=Path, default=None, help="folder of results.json and validation.log "
                   "(default: --out)")  # fmt: skip
    p.add_argument("--report", type=Path, default=None, metavar="RESULTS_JSON", help="render the page's section "
                   "from this results.json and exit (runs nothing; with --page)")  # fmt: skip
    p.add_argument("--page", type=Path, default=None, help="docs page whose generated section is rewritten")
    p.add_argument("--device", default="auto", help="Warp device: cpu, cuda:0, or auto (cuda:0 when present)")
    p.add_argument("--precision", choices=("fp64", "fp32"), default=None, help="precision of every experiment "
                   "(default: the stepping table's, settings.STEPPING)")  # fmt: skip
    p.add_argument("--engine", choices=("auto", "general", "onchip"), default="auto", help="HF engine")
    p.add_argument("--quick", action="store_true", help="the reduced CPU variant (small pads, short windows)")
    p.add_argument("--seeds", type=int_at_least(1), help=f"pads per experiment ({FULL.seeds}; quick {QUICK.seeds})")
    p.add_argument("--first-seed", type=int_at_least(0), default=None, help="seed of pad 0 (1: the presets' layout)")
    p.add_argument("--patches", type=int_at_least(2), help=f"patches per pad (preset's; quick {QUICK.patches})")
    p.add_argument("--dt", type=positive, default=None, help="time step [s] of every experiment (default: the "
                   "stepping table's, settings.STEPPING)")  # fmt: skip
    p.add_argument("--growth-dt", type=growth_spacing, default=None, metavar="S|scene", help="spacing [s] of the "
                   "growth events of the growing experiments (§3.2), each adding the growth of its spacing (default: "
                   f"the stepping table's, {STEPPING['growth'].growth_dt:g} s; 'scene': the scenes' own interval, the "
                   "paper's clock)")  # fmt: skip
    p.add_argument("--window", type=positive, help=f"window [s] ({FULL.window:g}; quick {QUICK.window:g})")
    p.add_argument("--perturbation", type=nonneg, help=f"initial velocity σ [m/s] ({FULL.perturbation:g})")
    p.add_argument("--settle-safety", type=positive, default=None, help=f"factor on the predicted settling time "
                   f"({FULL.settle_safety:g})")  # fmt: skip
    p.add_argument("--paper-length", type=positive, default=None, help=f"length of the runs from rest [s] "
                   f"({FULL.paper_length:g}; quick {QUICK.paper_length:g})")  # fmt: skip
    p.add_argument("--only", nargs="+", default=None, metavar="EXPERIMENT", help="run only these experiments "
                   "(the table still uses the saved results of the others)")  # fmt: skip
    p.add_argument("--max-wall", type=nonneg, default=None, help="wall-time budget [s]: a batch whose estimate (or "
                   "whose probe of its step time, after a warm-up) no longer fits is not run")  # fmt: skip
    p.add_argument("--growth-speedup", type=positive, default=None, help=f"compression of the varying-area growth of "
                   f"va and its variants ({FULL.growth_speedup:g}; quick {QUICK.growth_speedup:g})")  # fmt: skip
    p.add_argument("--state-patches", type=int_at_least(2), help=f"patches per LF state of the multi-timescale "
                   f"experiments (a sector; the whole state; quick {QUICK.state_patches})")  # fmt: skip
    p.add_argument("--workers", type=int_at_least(1), help="processes that analyse the pads of an experiment "
                   "(default: the CPU count less one, at most 15)")  # fmt: skip
    p.add_argument("--with", dest="with_results", type=Path, nargs="+", default=None, metavar="RESULTS_JSON",
                   help="take the finished experiments of earlier results.json files with the same settings as done: "
                   "a second call that runs what the first left out, or the join of runs made side by side with "
                   "--only on several GPUs (an experiment finished in two of the files is refused)")  # fmt: skip
    p.add_argument("--without", nargs="+", default=[], metavar="EXPERIMENT", help="leave these experiments of the "
                   "--with files out, so that they run again (after a change that concerns them only); give a new "
                   "--out, or --rerun: a result of theirs saved in --out is reused otherwise")  # fmt: skip
    p.add_argument("--lf-dir", type=Path, default=None, help="folder of the LF runs of the §3.3 experiments "
                   "(default DIR/lf): give shares run side by side, and a second call, the same folder (the LF "
                   "stage runs once; results cut from other LF runs are not joined)")  # fmt: skip
    p.add_argument("--rerun", action="store_true", help="run again even where a saved result fits")
    p.add_argument("--keep-records", action="store_true", help="also keep each run's records (globals and per-patch "
                   "velocities, DIR/<experiment>/records.npz: the per-patch record's size per experiment)")  # fmt: skip
    p.add_argument("--reanalyse", action="store_true", help="analyse kept records again instead of reusing the "
                   "saved results (experiments without records are run)")  # fmt: skip
    p.add_argument("--list", action="store_true", help="list the experiments and rows, then exit")
    p.add_argument("--dry-run", action="store_true", help="plan the batches (run lengths, steps, memory, the "
                   "estimate for --device), then exit; runs only the LF runs it needs, needs no GPU")  # fmt: skip
    return p


class TeeLog(Log):
    """A :class:`Log` that also appends every line to a file."""

    def __init__(self, path: Path | None) -> None:
        super().__init__()
        self.path = path
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text("")

    def __call__(self, message: str) -> None:
        super().__call__(message)
        if self.path is not None:
            with self.path.open("a") as f:
                f.write(f"[{self.elapsed():7.1f} s] {message}\n")


def batches_of(names: list[str]) -> list[tuple[str, list[str]]]:
    """The experiments ``names`` grouped into their batches, in registration order (a batch at its first member)."""
    out: dict[str, list[str]] = {}
    for name in EXPERIMENTS:
        if name in names:
            out.setdefault(EXPERIMENTS[name].batch or name, []).append(name)
    return list(out.items())


def dry_prepare(exp: Experiment, cfg: Config, log: Log) -> Prepared:
    """:func:`prepare` for the cost: an LF-state experiment is planned from every seed's LF run where ``cfg.lf_dir``
    holds them all (the first seed's run here if missing), else from the first seed's only (its states stand for
    every seed's, and the log says so: a denser state of another seed can push a batch's neighbour lists off chip,
    4.2× slower on an H200, docs/benchmarks/lf_batches_h200)."""
    if exp.builder is not validation_multiscale.state_scene:
        return prepare(exp, cfg)
    validation_multiscale.ensure_lf([exp.name], cfg, log, first_only=True)
    if not validation_multiscale.lf_jobs([exp.name], cfg):
        return prepare(exp, cfg)
    one = dataclasses.replace(cfg, seeds=1)
    log(f"{exp.name}: planned from LF seed {cfg.first_seed}'s states for all {cfg.seeds} seeds (the others' LF runs "
        f"are not in {cfg.lf_dir}; give --lf-dir a folder that holds them to plan from each)")  # fmt: skip
    p = prepare(exp, one)
    rep = cfg.seeds
    return Prepared(
        exp, [s for s in p.scenes for _ in range(rep)], [c for c in p.contacts for _ in range(rep)],
        [s for s in p.sigma for _ in range(rep)], p.plan, [m for m in p.members for _ in range(rep)],
    )  # fmt: skip


def dry_run(names: list[str], cfg: Config, log: Log) -> float:
    """Plan every batch of ``names`` and print its run length, step, steps, memory and estimate; the total [s] of
    stepping and overheads."""
    costs, total, batches = Costs(), 0.0, []
    lf_runs = len(validation_multiscale.lf_jobs(names, cfg))
    for key, members in batches_of(names):
        batch = make_batch(key, [dry_prepare(EXPERIMENTS[n], cfg, log) for n in members], cfg)
        batches.append(batch)
        bound = batch_friction_step(batch.scenes)
        step = cfg.stepping(batch.stepping_kind)
        steps = costs.steps(batch, cfg)
        per = costs.step(batch, cfg)
        total += steps * per
        p = batch.plan
        sig = np.median([np.percentile(s, [0, 50, 100]) for m in batch.members for s in m.sigma], axis=0)
        sizes = sorted({s.patches.count for s in batch.scenes})
        log(
            f"{key} ({', '.join(members)}): {len(batch.scenes)} pads × {'/'.join(map(str, sizes))} patches; σ_i "
            f"min/median/max {'/'.join(unsigned_zero(f'{x:.0f}') for x in sig)} 1/s; run {p.duration * 1e3:.1f} ms in "
            f"{len(p.segments)} segment(s); friction step {bound:.3g} s, {step.describe()}: "
            f"{steps:,} steps at {per * 1e6:.2f} µs/step = {steps * per:.0f} s on {cfg.device}; per-patch record "
            f"{sum(m.plan.velocity_bytes for m in batch.members) / 2**20:.0f} MiB"
        )
    extra = overheads(batches, cfg, lf_runs)
    log(f"total: estimated {total:.0f} s of stepping ({total / 60:.1f} min) in {len(batches)} batch(es)")
    log(
        f"beside it (estimates): kernel compilation {extra['compile']:.0f} s, {lf_runs} LF run(s) {extra['lf']:.0f} s, "
        f"analysis {extra['analysis']:.0f} s with {cfg.workers} worker(s); in all {total + sum(extra.values()):.0f} s "
        f"({(total + sum(extra.values())) / 60:.1f} min)"
    )
    return total + sum(extra.values())


def default_workers() -> int:
    """Analysis processes by default: the CPU count less one (the run loop's), at most 15."""
    import os

    return max(1, min(15, (os.cpu_count() or 1) - 1))


def growth_spacing(text: str) -> float | str:
    """``--growth-dt``: "scene", or a positive number of seconds."""
    return "scene" if text == "scene" else positive(text)


def default_experiments(quick: bool) -> list[str]:
    """The experiments a run without --only runs: every registered one except the opt-in ones and, in the quick
    variant, those marked full-variant only."""
    return [n for n, e in EXPERIMENTS.items() if not e.opt_in and not (quick and not e.quick)]


def config_from(args: argparse.Namespace, device: str) -> Config:
    """The settings: the quick or the full defaults, with the options given."""
    base = QUICK if args.quick else FULL
    over = {
        "seeds": args.seeds,
        "first_seed": args.first_seed,
        "patches": args.patches,
        "dt": args.dt,
        "growth_dt": args.growth_dt,
        "window": args.window,
        "perturbation": args.perturbation,
        "settle_safety": args.settle_safety,
        "precision": args.precision,
        "growth_speedup": args.growth_speedup,
        "paper_length": args.paper_length,
        "state_patches": args.state_patches,
        "workers": args.workers if args.workers is not None else default_workers(),
    }
    return dataclasses.replace(
        base, device=device, engine=args.engine, **{k: v for k, v in over.items() if v is not None}
    )


def _list() -> None:
    for name, exp in EXPERIMENTS.items():
        print(f"experiment {name:14} {exp.section:6} batch {exp.batch or name:10} {exp.description}")
    for row in ROWS:
        print(f"row {row.section:18} [{row.kind}] {row.statement}  [{', '.join(row.experiments)}]")


def run_all(
    names: list[str], cfg: Config, out: Path, log: Log, args: argparse.Namespace,
    done: Callable[[dict[str, dict]], None] | None = None, earlier: dict[str, dict] | None = None,
) -> dict:  # fmt: skip
    """Reuse, analyse again or run every experiment of ``names`` batch by batch; failures are logged and recorded
    (``args``: rerun, reanalyse, keep_records, max_wall). ``earlier``: finished results taken as done (``--with``;
    :func:`reusable`). ``done(results)`` after every batch (the results file is written then, so a run cut off keeps
    what it finished)."""
    earlier = earlier or {}
    results: dict[str, dict] = {}
    todo = []
    for name in names:
        fresh = args.rerun or args.reanalyse
        saved = earlier.get(name) if fresh else reusable(name, out, cfg, earlier)
        if saved is not None:
            results[name] = saved
            log(f"{name}: reusing the saved result")
        else:
            todo.append(name)
    try:
        validation_multiscale.ensure_lf(todo, cfg, log)
    except Exception as e:  # noqa: BLE001 (the experiments that need the LF runs fail below, the others go on)
        log(f"LF runs: FAILED: {type(e).__name__}: {e}")
    for name, why in lf_refusals(todo, earlier, cfg).items():
        log(f"{name}: {why}")
        results[name] = {"status": f"failed: {why}", "pads": []}
        todo.remove(name)
    costs = Costs()
    for key, members in batches_of(todo):
        preps = []
        for name in members:
            try:
                prep = prepare(EXPERIMENTS[name], cfg)
                again = reanalyse(prep, cfg, out, log) if args.reanalyse else None
                if again is not None:
                    results[name] = again
                else:
                    preps.append(prep)
            except Exception as e:  # noqa: BLE001 (one experiment must not stop the others)
                results[name] = _failed(out, name, e, log)
        if not preps:
            continue
        budget = None if args.max_wall is None else args.max_wall - log.elapsed()
        try:
            results.update(run_batch(make_batch(key, preps, cfg), cfg, out, log, costs, budget, args.keep_records))
        except Exception as e:  # noqa: BLE001
            for p in preps:
                results[p.exp.name] = _failed(out, p.exp.name, e, log)
        if done is not None:
            done(results)
    return results


@dataclass
class Earlier:
    """What ``--with`` takes from earlier results files: the finished experiments, the provenance of each call that
    ran some of them (command, date, machine, wall time, its experiments; :func:`runs_of`) and the files' §3.3 LF
    facts (None if none has any)."""

    results: dict[str, dict] = field(default_factory=dict)
    parts: list[dict] = field(default_factory=list)
    lf: dict | None = None


def earlier_results(
    paths: list[Path] | None, cfg: Config, log: Callable[[str], None], without: Sequence[str] = ()
) -> Earlier:
    """The finished experiments of earlier ``results.json`` files made with the same settings (``--with``), less those
    named in ``without`` (``--without``: they run again); a file of
    other settings is logged and left out, and so is a result made with another stepping of its kind
    (:func:`~aca_warp.studies.validation.base.same_settings`) or another definition of its experiment (as a
    saved checkpoint would be) or a §3.3 result that does not record the LF runs it was cut from (it could be
    joined with results of other LF runs unseen). ValueError for a file that is not a results file, an
    experiment finished in two of them (which to take would be a guess), or §3.3 results cut from different LF
    runs."""
    from aca_warp.studies.validation.results import read_results

    got = Earlier()
    key = cfg.run_key()
    source: dict[str, Path] = {}
    runs: dict[str, dict[str, str]] = {}
    for path in paths or []:
        results, meta, _ = read_results(path)
        if not same_settings(meta["config"], key, None):
            log(f"{path}: other settings than this run's; not used")
            continue
        done = {n: r for n, r in results.items() if n in EXPERIMENTS and r.get("status") in ("done", "stopped")}
        stepped = [n for n, r in done.items() if not same_settings(r.get("config") or meta["config"], key,
                                                                   EXPERIMENTS[n].stepping)]  # fmt: skip
        if stepped:
            log(f"{path}: {', '.join(sorted(stepped))} not used: made with another stepping of their kind")
            done = {n: r for n, r in done.items() if n not in stepped}
        dropped = sorted(set(done) & set(without))
        if dropped:
            log(f"{path}: {', '.join(dropped)} not used: run again (--without)")
            done = {n: r for n, r in done.items() if n not in dropped}
        stale = [n for n, r in done.items() if not same_definition(r, EXPERIMENTS[n])]
        if stale:
            log(f"{path}: {', '.join(stale)} not used: made with another definition of the experiment")
            done = {n: r for n, r in done.items() if n not in stale}
        lf_state = validation_multiscale.state_scene
        blind = [n for n, r in done.items() if EXPERIMENTS[n].builder is lf_state and not r.get("lf_runs")]
        if blind:
            log(f"{path}: {', '.join(blind)} not used: no record of the LF runs they were cut from")
            done = {n: r for n, r in done.items() if n not in blind}
        twice = sorted(set(done) & set(got.results))
        if twice:
            raise ValueError(f"{path}: {', '.join(twice)} finished in {source[twice[0]]} as well; give each once")
        got.results.update(done)
        source.update(dict.fromkeys(done, path))
        runs.update({f"{n} in {path}": r.get("lf_runs", {}) for n, r in done.items()})
        if results.get("lf_states", {}).get("lf_runs"):
            runs[f"the LF facts in {path}"] = results["lf_states"]["lf_runs"]
            got.lf = got.lf or results["lf_states"]
        got.parts += runs_of(meta, sorted(done))
        log(f"{path}: taking {len(done)} finished experiment(s) as done")
    clash = validation_multiscale.lf_conflicts(runs)
    if clash:
        raise ValueError(
            f"§3.3 results made from different LF runs: {'; '.join(clash)}; run every share, and a second call, "
            "with one --lf-dir"
        )
    return got


def runs_of(meta: dict[str, Any], done: list[str]) -> list[dict[str, Any]]:
    """The calls that finished the experiments ``done`` of a results file with provenance ``meta``, for the page:
    the earlier calls the file itself took experiments from (its ``with``), each with those of ``done`` it finished,
    then the file's own call with the rest (command, created, machine, wall time and experiments each), so that a
    join of a joined file still names the call that ran each experiment."""
    parts, left = [], list(done)
    for part in meta.get("with") or []:
        theirs = set(part.get("experiments", []))
        mine = [n for n in left if n in theirs]
        if mine:
            parts.append({**part, "experiments": mine})
            left = [n for n in left if n not in mine]
    if left:
        parts.append({k: meta.get(k) for k in ("command", "created", "machine", "wall_s")} | {"experiments": left})
    return parts


def reusable(name: str, out: Path, cfg: Config, earlier: dict[str, dict]) -> dict | None:
    """The finished result of ``name`` that a call takes as done: that of the ``earlier`` results (``--with``), else
    the one saved in ``out / name`` when it fits the settings and its LF runs (:func:`load_result`) and those are
    the files the earlier results were cut from (:func:`lf_refusals`); None when there is none."""
    if name in earlier:
        return earlier[name]
    saved = load_result(out / name, EXPERIMENTS[name], cfg)
    return None if saved is None or lf_refusals([name], earlier, cfg) else saved


def lf_refusals(todo: list[str], earlier: dict[str, dict], cfg: Config) -> dict[str, str]:
    """The §3.3 experiments of ``todo`` whose LF runs in ``cfg.lf_dir`` are not the files that the ``earlier``
    results were cut from, each with the reason (they are not run: their results could not be joined)."""
    theirs = {f"{n} (earlier)": r.get("lf_runs", {}) for n, r in earlier.items()}
    out = {}
    for name in todo:
        mine = validation_multiscale.lf_runs(EXPERIMENTS[name], cfg)
        clash = validation_multiscale.lf_conflicts({**theirs, name: mine}) if mine and theirs else []
        if clash:
            out[name] = (
                f"not run: its LF runs in {cfg.lf_dir} are not those of the earlier results ({'; '.join(clash)}); "
                "give --lf-dir their folder"
            )
    return out


def _failed(out: Path, name: str, e: Exception, log: Log) -> dict[str, Any]:
    import traceback

    (out / name).mkdir(parents=True, exist_ok=True)
    (out / name / "error.txt").write_text(traceback.format_exc())
    log(f"{name}: FAILED: {type(e).__name__}: {e} (traceback in {out / name / 'error.txt'})")
    return {"status": f"failed: {type(e).__name__}: {e}", "pads": []}


def write_page(results_json: Path, page: Path | None, out_md: Path | None, log: Log) -> list[dict]:
    """Render the generated section from ``results_json``; write it to ``out_md`` (whole) and into ``page``."""
    body, rows, _ = render_report(results_json)
    if out_md is not None:
        out_md.write_text("# Validation\n\n" + "\n".join(body) + "\n")
    if page is not None:
        replace_generated(page, body, generated_markers(MARKER), "Validation")
    log(f"rendered {len(rows)} rows from {results_json}" + (f" into {page}" if page else ""))
    return rows


FOLDERS = {"--out": "DIR", "--results": "RESULTS", "--with": "EARLIER_RESULTS_JSON", "--lf-dir": "LF_DIR"}
"""Options whose value is a folder or file of the machine that ran: named by their role in the recorded command."""


def portable(argv: list[str]) -> list[str]:
    """``argv`` with the values of :data:`FOLDERS` replaced by their role (the run's folders are not the reader's;
    every value of ``--with``, which takes several; also as ``--out=DIR`` and under an abbreviated option name, as
    argparse takes them)."""
    out: list[str] = []
    role, many = None, False
    for a in argv:
        if a.startswith("--"):
            name, eq, _ = a.partition("=")
            keys = [k for k in FOLDERS if k.startswith(name)] if len(name) > 2 else []
            role = FOLDERS[keys[0]] if len(keys) == 1 else None
            many = role is not None and keys[0] == "--with"
            out.append(f"{name}={role}" if eq and role is not None else a)
            role = None if eq else role
        elif role is not None:
            out.append(role)
            role = role if many else None
        else:
            out.append(a)
    return out


def meta_of(argv: list[str], wp: Any, device: str, cfg: Config) -> dict[str, Any]:
    """The provenance of a run: its command, time, machine, versions and settings."""
    from aca_warp.common.files import machine, versions

    return {
        "command": command_line("validation.py", portable(argv)),
        "created": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": machine(wp.get_device(device))["device_name"],
        "versions": versions(),
        "config": cfg.run_key(),
    }


class ResultsWriter:
    """Writes ``results.json`` (called after every batch, and at the end with ``final``): the results so far, every
    other finished result the call may take (:func:`reusable`: those of ``--with``, those saved in ``out``), the LF
    facts once the multi-timescale experiments have results (those of the earlier results when ``--with`` brought
    any), and the provenance with the wall time so far."""

    def __init__(
        self, path: Path, out: Path, cfg: Config, log: Log, meta: dict[str, Any], earlier: Earlier | None = None
    ) -> None:
        self.path, self.out, self.cfg, self.log, self.meta = path, out, cfg, log, meta
        self.earlier = earlier or Earlier()
        self.lf = self.earlier.lf  # the LF facts of the earlier results (--with), else made once from cfg.lf_dir

    def __call__(self, results: dict[str, dict], final: bool = False) -> Path:
        every = dict(results)
        for name in EXPERIMENTS:
            saved = None if name in every else reusable(name, self.out, self.cfg, self.earlier.results)
            if saved is not None:
                every[name] = saved
        if any(n in EXPERIMENTS and EXPERIMENTS[n].builder is validation_multiscale.state_scene for n in every):
            self.lf = self.lf or validation_multiscale.lf_facts(self.cfg)
            every["lf_states"] = self.lf
        spent = sum((r.get("total_s") or 0.0) + (r.get("analysis_s") or 0.0) for r in every.values())
        meta = {**self.meta, "wall_s": self.log.elapsed(), "experiments_s": spent, "complete": final}
        return write_results(self.path, every, meta)


def _check_outputs(page: Path | None, *folders: Path | None) -> None:
    """AcaError for a --page that cannot be written or an output folder that cannot be made (nothing written)."""
    from aca_warp.common.files import check_output_folder, check_output_path

    if page is not None:
        check_output_path(page, overwrite=True)
    for folder in folders:
        if folder is not None:
            check_output_folder(folder)


def main(argv: list[str] | None = None) -> int:
    """Run the selected experiments, write results.json, the log and --page; 0 unless the input is bad (2)."""
    from aca_warp.studies.report import init_warp

    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    if args.list:
        _list()
        return 0
    if args.report is not None:
        if not args.report.is_file():
            print(f"validation.py: no results file {args.report}", file=sys.stderr)
            return 2
        try:
            _check_outputs(args.page)
            write_page(args.report, args.page, None, Log())
        except (AcaError, ValueError) as e:
            print(f"validation.py: {e}", file=sys.stderr)
            return 2
        return 0
    names = args.only or default_experiments(args.quick)
    unknown = [n for n in [*names, *args.without] if n not in EXPERIMENTS]
    if unknown:
        print(f"validation.py: unknown experiment(s) {', '.join(unknown)}; see --list", file=sys.stderr)
        return 2
    if args.without and not args.with_results:
        print("validation.py: --without leaves experiments of --with files out; give --with", file=sys.stderr)
        return 2
    if args.dry_run:
        cfg = config_from(args, "cpu" if args.device == "auto" else args.device)
        try:  # the estimates need no device; the LF runs it has to make need --device
            dry_run(names, dataclasses.replace(cfg, lf_dir=str(args.lf_dir or args.out / "lf")), Log())
        except SceneError as e:
            print(f"validation.py: {e}; the dry run makes the LF runs it lacks on --device: plan with --device cpu, "
                  "or give --lf-dir a folder that holds them", file=sys.stderr)  # fmt: skip
            return 2
        return 0
    notes: list[str] = []  # what --with left out, for the log once it is opened
    try:  # before anything is written: the device does not enter the settings compared
        earlier = earlier_results(args.with_results, config_from(args, "cpu"), notes.append, args.without)
        _check_outputs(args.page, args.out, args.results, args.lf_dir)
    except (AcaError, ValueError) as e:
        print(f"validation.py: {e}", file=sys.stderr)
        return 2
    wp = init_warp()
    device = ("cuda:0" if wp.is_cuda_available() else "cpu") if args.device == "auto" else args.device
    try:
        get_device(device)
    except SceneError as e:
        print(f"validation.py: {e}", file=sys.stderr)
        return 2
    results_dir = args.results or args.out
    log = TeeLog(results_dir / "validation.log")
    cfg = dataclasses.replace(config_from(args, device), lf_dir=str(args.lf_dir or args.out / "lf"))
    args.out.mkdir(parents=True, exist_ok=True)
    log(f"validation ({'quick' if cfg.quick else 'full'}): {', '.join(names)} on {device} -> {args.out}")
    for note in notes:
        log(note)
    if earlier.parts:
        log(f"taking {len(earlier.results)} finished experiment(s) of {len(earlier.parts)} earlier call(s) as done "
            "(--with)")  # fmt: skip
    meta = meta_of(argv, wp, device, cfg) | ({"with": earlier.parts} if earlier.parts else {})
    save = ResultsWriter(results_dir / "results.json", args.out, cfg, log, meta, earlier)
    path = save(run_all(names, cfg, args.out, log, args, save, earlier.results), final=True)
    log(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")
    rows = write_page(path, args.page, results_dir / "validation.md", log)
    for r in rows:
        print(f"  {r['verdict']:26} {r['statement']}")
    close_pools()
    return 0


if __name__ == "__main__":
    sys.exit(main())
