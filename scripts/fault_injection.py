"""Random SIGKILLs (or Ctrl-C, SIGTERM) of ``aca-warp hf``, ``lf`` and ``sweep``, then recovery, compared with
uninterrupted runs.

For each workload (a small HF scene with per-patch histories and checkpoints, a small LF scene with checkpoints and
snapshots, a four-shard sweep) the script runs the command once without interruption (the reference), then, per
trial, starts it in a subprocess and kills it with SIGKILL after a random delay (uniform over the reference's wall
time, start-up included, so kills land before, during and after the file appears and between and inside
checkpoints). The recovery then does what a user would:

* HF / LF: ``--resume`` the ``.partial`` (or the stopped file; one killed before its first checkpoint starts again
  from t = 0); a run killed before its file existed runs again; with probability 1/2 the recovery itself is killed
  at a random time too (at most ``--max-kills`` kills per trial) and recovered again;
* sweep: the same command again (a sweep resumes by design).

With ``--signals INT,TERM`` (any of KILL, INT, TERM; default KILL) each kill of an HF or LF run sends one of these
signals, chosen at random (a sweep always gets SIGKILL). A run that takes a SIGINT or SIGTERM must end with exit
130 or 143 and exactly one ``aca-warp: interrupted`` line, no traceback (or exit 0, when it finished first); a
signal that lands before Python has started the command (the interpreter's start-up: SIGTERM's default action,
Python's own KeyboardInterrupt) is counted as ``early``, as nothing was written then. The recovery resumes the
interrupted file (``RUN.h5``, marked incomplete) as it resumes a killed run's ``.partial``.

With ``--file-size-limits N`` each workload also runs N times under a file-size limit (RLIMIT_FSIZE, SIGXFSZ
ignored: a write past it fails with EFBIG, the path of a full device), the limits spread evenly from 30 % to
110 % of the reference output's size (a sweep: of its largest shard); the run must stop with exit 4 (or finish,
when the limit is not reached), and its recovery without the limit must again equal the reference.

A trial passes when the recovered output equals the reference dataset for dataset, bit for bit (HF: every dataset
of the run file; LF: every dataset, snapshots included; sweep: every dataset of every shard file), every recovery
command exited 0 and no ``.partial`` or lock is left. Counts and failures are printed and written as JSON and
Markdown.

    python scripts/fault_injection.py --kills 12 --file-size-limits 6    # ~12 minutes on the 2-core container
    python scripts/fault_injection.py --quick                            # one trial per workload, short runs
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path

import h5py
import numpy as np
from small_scenes import small_lf_scene_toml, small_scene_toml, three_applications

from aca_warp.common.argtypes import int_at_least
from aca_warp.common.errors import AcaError
from aca_warp.common.files import check_output_folder, check_output_path, host_cpu


def hf_scene(duration: float, patches: tuple[str, ...] = ("velocity", "displacement")) -> str:
    """The HF workload: 40 patches, perturbed, per-patch ``patches`` histories over ``duration`` [s]."""
    return small_scene_toml("fi-hf", count=40, duration=duration, sample_dt=1.0e-6, patches=patches, perturbation=1e-3)


def lf_scene(first: float) -> str:
    """The LF workload: births, stores and merges, snapshots at every application; 300 N for ``first`` [s] first."""
    lf = {"wear_m": 2e-12, "p_birth": 1.0, "p_store": 0.3, "compact_every": 25}
    return small_lf_scene_toml("fi-lf", three_applications(first), lf=lf, snapshots={"applications": True})


SWEEP_SPEC = """
[sweep]
base = "base.toml"
shard_size = 1
name = "fi-sweep"
[run]
duration = {duration}
[parameters]
"friction.M" = [0.6, 0.7, 0.8, 0.9]
"""


@dataclass
class Workload:
    """One command under test: how to start it, recover it and read its output."""

    name: str
    start: list[str]  # argv after ``aca-warp`` of the uninterrupted command (output OUT)
    output: str  # OUT: a file (hf, lf) or a folder (sweep)


LIMITED = (
    "import resource, signal, sys; lim = int(sys.argv[1]); signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
    "resource.setrlimit(resource.RLIMIT_FSIZE, (lim, lim)); from aca_warp.cli import run; run(sys.argv[2:])"
)


@dataclass
class Trial:
    """What one trial did."""

    workload: str
    limit: int | None = None  # file-size limit [bytes] of a disk-full trial
    stopped: int | None = None  # exit code of the limited run
    kills: int = 0
    delays: list[float] = field(default_factory=list)
    signals: list[str] = field(default_factory=list)  # the signal of each kill: KILL, INT, TERM
    early: int = 0  # SIGINT/SIGTERM that landed before the command's handlers (interpreter start-up)
    recoveries: list[str] = field(default_factory=list)  # resume, rerun, sweep-rerun, finished
    outcome: str = ""  # identical, different, error
    detail: str = ""
    seconds: float = 0.0


WORKLOADS = ("hf", "lf", "sweep")  # the names of :func:`workloads`, in its order


def workloads(root: Path, quick: bool) -> list[Workload]:
    """The three workloads, their scene files written into ``root``."""
    hf = root / "hf.toml"
    hf.write_text(hf_scene(5e-4 if quick else 2e-3))
    lf = root / "lf.toml"
    lf.write_text(lf_scene(1.0 if quick else 4.0))
    base = root / "base.toml"
    base.write_text(hf_scene(1e-4, patches=()))
    spec = root / "spec.toml"
    spec.write_text(SWEEP_SPEC.format(duration="1e-4" if quick else "3e-4"))
    return [
        Workload("hf", ["hf", str(hf), "--no-progress", "--checkpoint-interval", "1e-4"], "hf.h5"),
        Workload("lf", ["lf", str(lf), "--no-progress", "--checkpoint-interval", "0.1"], "lf.h5"),
        Workload("sweep", ["sweep", str(spec), "--workers", "0", "--quiet"], "sweep"),
    ]


def env() -> dict[str, str]:
    return dict(os.environ)


def cli(args: list[str], cwd: Path, limit: int | None = None) -> subprocess.Popen:
    pre = [sys.executable, "-m", "aca_warp.cli"] if limit is None else [sys.executable, "-c", LIMITED, str(limit)]
    return subprocess.Popen(
        [*pre, *args],
        cwd=cwd,
        env=env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )


def run_to_end(args: list[str], cwd: Path, limit: int | None = None) -> tuple[int, str]:
    p = cli(args, cwd, limit)
    _, err = p.communicate(timeout=600)
    return p.returncode, err


SIGNALS = {"KILL": signal.SIGKILL, "INT": signal.SIGINT, "TERM": signal.SIGTERM}


def run_and_kill(args: list[str], cwd: Path, delay: float, sig: str = "KILL") -> tuple[bool, int, str]:
    """Start ``aca-warp ARGS``, send it SIG{sig} after ``delay`` s; (killed, exit code, stderr): killed is False
    when it ended by itself before (then its exit code and stderr count). A SIGINT or SIGTERM must end the command
    as :func:`interrupted` checks (else RuntimeError, which the trial reports)."""
    p = cli(args, cwd)
    try:
        _, err = p.communicate(timeout=delay)
        return False, p.returncode, err
    except subprocess.TimeoutExpired:
        p.send_signal(SIGNALS[sig])
        _, err = p.communicate(timeout=600)
    if sig == "KILL":
        return True, -signal.SIGKILL, ""
    return interrupted(p.returncode, err, SIGNALS[sig])


def interrupted(code: int, err: str, sig: int) -> tuple[bool, int, str]:
    """Judge how a command ended after SIGINT/SIGTERM ``sig``: exit 128 + sig with one ``aca-warp: interrupted``
    line and no traceback (killed), exit 0 (it finished first: not killed), or ``early`` (the signal came before
    the command's handlers: SIGTERM's default action, or Python's KeyboardInterrupt at start-up; exit code -sig
    or 1 with ``KeyboardInterrupt`` and no ``aca-warp`` line)."""
    lines = [x for x in err.splitlines() if x.strip() and not x.startswith("Warp ")]
    if code == 128 + sig and len(lines) == 1 and lines[0].startswith("aca-warp: interrupted"):
        return True, code, err
    if code == 0:
        return False, 0, err
    if code == -sig or (code == 1 and "KeyboardInterrupt" in err and "aca-warp" not in err):
        return True, -1, err  # -1: early
    raise RuntimeError(f"signal {sig}: exit {code}, {len(lines)} line(s): {' | '.join(lines[-3:])}")


def complete(path: Path) -> bool:
    """Whether the run file ``path`` says it is complete (an interrupted one says not)."""
    with h5py.File(path, "r") as f:
        return bool(f.attrs.get("complete", False))


def datasets(path: Path) -> dict[str, bytes]:
    """Every dataset of an HDF5 file (dtype, shape and bytes)."""
    out: dict[str, bytes] = {}
    with h5py.File(path, "r") as f:

        def visit(name: str, obj: object) -> None:
            if isinstance(obj, h5py.Dataset):
                a = np.asarray(obj[()])
                out[name] = repr((a.dtype.str, a.shape)).encode() + a.tobytes()

        f.visititems(visit)
    return out


def output_datasets(w: Workload, cwd: Path) -> dict[str, bytes]:
    """Every dataset of a workload's output (a sweep: of every shard file, keyed by shard)."""
    out = cwd / w.output
    if w.name != "sweep":
        return datasets(out)
    merged: dict[str, bytes] = {}
    for shard in sorted(out.glob("shard-*.h5")):
        merged.update({f"{shard.name}/{k}": v for k, v in datasets(shard).items()})
    states = [s["state"] for s in json.loads((out / "manifest.json").read_text())["shards"]]
    merged["manifest/states"] = repr(states).encode()
    return merged


def leftovers(w: Workload, cwd: Path) -> list[str]:
    """Files a finished workload must not leave: ``.partial``, ``.partial.new``, locks."""
    where = cwd / w.output if w.name == "sweep" else cwd
    return sorted(p.name for p in where.iterdir() if p.name.endswith((".partial", ".new", ".lock")))


def recover(
    w: Workload, cwd: Path, t: Trial, rng: random.Random, budget: float, max_kills: int, signals: list[str]
) -> tuple[int, str]:
    """Bring a killed workload to its end (possibly killing the recovery again); returns the last exit code and
    stderr."""
    out = cwd / w.output
    while True:
        if w.name == "sweep":
            args, what = [*w.start, "-o", str(out)], "sweep-rerun"
        elif out.exists() and complete(out):
            t.recoveries.append("finished")
            return 0, ""
        elif out.exists() or out.with_name(out.name + ".partial").exists():  # interrupted, or killed
            args, what = [w.name, "--resume", str(out), "--no-progress"], "resume"
        else:
            args, what = [*w.start, "-o", str(out)], "rerun"
        if t.kills < max_kills and rng.random() < 0.5:
            delay = rng.uniform(0.0, budget)
            t.delays.append(round(delay, 3))
            killed, code, err = kill(t, w, args, cwd, delay, rng, signals)
            if killed:
                t.recoveries.append(f"{what} (killed)")
                continue
        else:
            code, err = run_to_end(args, cwd)
        t.recoveries.append(what)
        return code, err


def kill(
    t: Trial, w: Workload, args: list[str], cwd: Path, delay: float, rng: random.Random, signals: list[str]
) -> tuple[bool, int, str]:
    """One kill of ``args`` after ``delay`` s with a signal drawn from ``signals`` (a sweep: SIGKILL), counted in
    ``t``; (killed, exit code, stderr)."""
    sig = "KILL" if w.name == "sweep" else rng.choice(signals)
    killed, code, err = run_and_kill(args, cwd, delay, sig)
    if killed:
        t.kills += 1
        t.signals.append(sig)
        t.early += code == -1
    return killed, code, err


@contextmanager
def reported(t: Trial, cwd: Path) -> Iterator[None]:
    """The frame of one trial working in ``cwd`` (made here): an exception of the body is ``t``'s error (the harness
    reports, it does not stop); ``t.seconds`` is the time it took; an identical trial's folder is removed."""
    t0 = time.perf_counter()
    cwd.mkdir()
    try:
        yield
    except Exception as e:  # noqa: BLE001
        t.outcome, t.detail = "error", f"{type(e).__name__}: {e}"
    finally:
        t.seconds = round(time.perf_counter() - t0, 2)
        if t.outcome == "identical":
            shutil.rmtree(cwd, ignore_errors=True)


def trial(
    w: Workload,
    root: Path,
    ref: dict[str, bytes],
    budget: float,
    rng: random.Random,
    max_kills: int,
    signals: list[str],
) -> Trial:
    t = Trial(w.name)
    cwd = root / f"trial-{w.name}-{rng.randrange(10**9)}"
    with reported(t, cwd):
        delay = rng.uniform(0.0, budget)
        t.delays.append(round(delay, 3))
        killed, code, err = kill(t, w, [*w.start, "-o", str(cwd / w.output)], cwd, delay, rng, signals)
        if killed:
            code, err = recover(w, cwd, t, rng, budget, max_kills, signals)
        else:
            t.recoveries.append("finished before the kill")
        compare(t, w, cwd, ref, code, err)
    return t


def compare(t: Trial, w: Workload, cwd: Path, ref: dict[str, bytes], code: int, err: str) -> None:
    """Set ``t.outcome``: the recovered output against the reference."""
    if code != 0:
        t.outcome, t.detail = "error", f"exit {code}: {err.strip().splitlines()[-1] if err.strip() else ''}"
    elif leftovers(w, cwd):
        t.outcome, t.detail = "error", f"left behind: {', '.join(leftovers(w, cwd))}"
    else:
        got = output_datasets(w, cwd)
        diff = sorted(set(got) ^ set(ref)) + sorted(k for k in set(got) & set(ref) if got[k] != ref[k])
        t.outcome = "identical" if not diff else "different"
        t.detail = ", ".join(diff[:5])


def output_size(w: Workload, cwd: Path) -> int:
    """Bytes of a workload's output (a sweep: its largest shard)."""
    out = cwd / w.output
    return out.stat().st_size if w.name != "sweep" else max(p.stat().st_size for p in out.glob("shard-*.h5"))


def limit_trial(w: Workload, root: Path, ref: dict[str, bytes], limit: int, rng: random.Random) -> Trial:
    """Run ``w`` under a file-size limit of ``limit`` bytes, then recover it without the limit and compare."""
    t = Trial(w.name, limit=limit)
    cwd = root / f"limit-{w.name}-{limit}"
    with reported(t, cwd):
        code, err = run_to_end([*w.start, "-o", str(cwd / w.output)], cwd, limit)
        t.stopped = code
        lines = [x for x in err.splitlines() if x.strip() and not x.startswith("Warp ")]
        if code not in (0, 4) or (code == 4 and (len(lines) != 1 or "file size limit reached" not in lines[0])):
            t.outcome, t.detail = "error", f"limited run: exit {code}: {' | '.join(lines[-2:])}"
        else:
            code, err = recover(w, cwd, t, rng, 0.0, 0, ["KILL"]) if code == 4 else (0, "")
            compare(t, w, cwd, ref, code, err)
    return t


def machine() -> str:
    """The CPU model, core count and platform of this machine."""
    return f"{host_cpu()}, {platform.platform()}"


def summarize(trials: list[Trial], refs: dict[str, float], args: argparse.Namespace) -> dict:
    by = {}
    for name in refs:
        ts = [t for t in trials if t.workload == name and t.limit is None]
        lim = [t for t in trials if t.workload == name and t.limit is not None]
        by[name] = {
            "limit_trials": len(lim),
            "limit_stopped_exit4": sum(t.stopped == 4 for t in lim),
            "limit_finished": sum(t.stopped == 0 for t in lim),
            "limit_recovered_identical": sum(t.outcome == "identical" for t in lim),
            "trials": len(ts),
            "kills": sum(t.kills for t in ts),
            "signals": {k: sum(t.signals.count(k) for t in ts) for k in SIGNALS},
            "early": sum(t.early for t in ts),
            "resumes": sum(r.startswith("resume") for t in ts for r in t.recoveries),
            "reruns": sum(r.startswith("rerun") for t in ts for r in t.recoveries),
            "sweep_reruns": sum(r.startswith("sweep-rerun") for t in ts for r in t.recoveries),
            "identical": sum(t.outcome == "identical" for t in ts),
            "different": sum(t.outcome == "different" for t in ts),
            "errors": sum(t.outcome == "error" for t in ts),
            "reference_wall_s": round(refs[name], 2),
        }
    return {
        "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "machine": machine(),
        "seed": args.seed,
        "workloads": by,
        "failures": [asdict(t) for t in trials if t.outcome != "identical"],
        "trials": [asdict(t) for t in trials],
    }


def markdown(s: dict) -> str:
    lines = [
        f"Fault injection: `{s['command']}` (seed {s['seed']}) on {s['machine']}.",
        "",
        "| workload | trials | kills (KILL/INT/TERM; early) | resumes | reruns | recovered bit-identical | different "
        "| errors |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, w in s["workloads"].items():
        reruns = w["reruns"] + w["sweep_reruns"]
        by = "/".join(str(w["signals"][k]) for k in SIGNALS)
        lines.append(
            f"| {name} | {w['trials']} | {w['kills']} ({by}; {w['early']}) | {w['resumes']} | {reruns} | "
            f"{w['identical']} | {w['different']} | {w['errors']} |"
        )
    if any(w["limit_trials"] for w in s["workloads"].values()):
        lines += [
            "",
            "| workload | file-size limits | stopped, exit 4 | finished under the limit | recovered bit-identical |",
            "|---|---|---|---|---|",
        ]
        for name, w in s["workloads"].items():
            lines.append(
                f"| {name} | {w['limit_trials']} | {w['limit_stopped_exit4']} | {w['limit_finished']} | "
                f"{w['limit_recovered_identical']} |"
            )
    for f in s["failures"]:
        where = f"limit {f['limit']} B" if f["limit"] is not None else f"kills at {f['delays']} s"
        lines.append(f"\nFAILED {f['workload']}: {f['outcome']} {f['detail']} ({where})")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog="See docs/faults.md.")
    p.add_argument(
        "--kills", type=int_at_least(0), default=10, help="trials per workload (each kills at least once; default 10)"
    )
    p.add_argument(
        "--max-kills", type=int_at_least(1), default=3, help="most SIGKILLs in one trial, recoveries included"
    )
    p.add_argument(
        "--file-size-limits",
        type=int_at_least(0),
        default=0,
        metavar="N",
        help="also run each workload under N file-size limits (30-110 %% of its output) and recover it",
    )
    p.add_argument(
        "--signals",
        default="KILL",
        help="comma-separated signals of the kills of hf and lf runs, drawn at random: KILL, INT, TERM (default KILL)",
    )
    p.add_argument("--workloads", default=",".join(WORKLOADS), help="comma-separated subset of hf, lf, sweep")
    p.add_argument("--seed", type=int, default=1, help="random seed of the kill times")
    p.add_argument("--quick", action="store_true", help="short runs, one trial per workload (used by the tests)")
    p.add_argument("--dir", type=Path, help="work folder (default: a new temporary folder, removed when all pass)")
    p.add_argument("--json", type=Path, help="write the summary as JSON here")
    p.add_argument("--markdown", type=Path, help="write the summary table as Markdown here")
    args = p.parse_args(argv)
    signals = args.signals.split(",")
    if not set(signals) <= set(SIGNALS):
        p.error(f"--signals takes {', '.join(SIGNALS)}")
    wanted = args.workloads.split(",")
    unknown = [w for w in wanted if w not in WORKLOADS]
    if unknown:
        p.error(f"--workloads: unknown {', '.join(map(repr, unknown))}; choose from {', '.join(WORKLOADS)}")
    try:  # every refusal before the first run: nothing run, nothing written
        for out in (args.json, args.markdown):
            if out is not None:
                check_output_path(out, overwrite=True)
        if args.dir is not None:
            check_output_folder(args.dir)
    except AcaError as e:
        p.error(str(e))
    if args.quick:
        args.kills = 1
    import tempfile

    root = args.dir or Path(tempfile.mkdtemp(prefix="aca-warp-faults-"))
    root.mkdir(parents=True, exist_ok=True)
    rng = random.Random(args.seed)
    trials: list[Trial] = []
    refs: dict[str, float] = {}
    for w in workloads(root, args.quick):
        if w.name not in wanted:
            continue
        ref_dir = root / f"reference-{w.name}"
        ref_dir.mkdir(exist_ok=True)
        t0 = time.perf_counter()
        code, err = run_to_end([*w.start, "-o", str(ref_dir / w.output)], ref_dir)
        refs[w.name] = time.perf_counter() - t0
        if code != 0:
            print(f"{w.name}: the uninterrupted run failed (exit {code}): {err.strip()}", file=sys.stderr)
            return 1
        ref = output_datasets(w, ref_dir)
        size = output_size(w, ref_dir)
        n = args.file_size_limits
        for limit in (int(size * (0.3 + 0.8 * i / max(n - 1, 1))) for i in range(n)):
            t = limit_trial(w, root, ref, limit, rng)
            trials.append(t)
            print(f"{w.name} limit {limit} B: exit {t.stopped}, {t.outcome} ({t.seconds} s) {t.detail}", flush=True)
        for k in range(args.kills):
            t = trial(w, root, ref, refs[w.name], rng, args.max_kills, signals)
            trials.append(t)
            steps = " -> ".join(t.recoveries) or "nothing to recover"
            print(
                f"{w.name} {k + 1}/{args.kills}: {t.outcome} after {t.kills} kill(s) ({', '.join(t.signals)}) at "
                f"{t.delays} s, {steps} "
                f"({t.seconds} s) {t.detail}",
                flush=True,
            )
    s = summarize(trials, refs, args)
    text = markdown(s)
    print(text)
    if args.json:
        args.json.write_text(json.dumps(s, indent=1))
    if args.markdown:
        args.markdown.write_text(text)
    ok = all(t.outcome == "identical" for t in trials)
    if ok and args.dir is None:
        shutil.rmtree(root, ignore_errors=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
