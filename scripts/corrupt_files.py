"""Single-bit flips and truncations of run files, fed to every command that reads them.

Builds the inputs (an HF run with per-patch velocities, an HF run stopped at its first checkpoint, an LF run with
snapshots and an LF run stopped at its first checkpoint), then for each reading command flips one bit at
``--flips`` offsets of its input (a dozen fixed offsets in the first 3 kB, where the superblock and the root group
live, the rest drawn at random over the file and its last 4 kB) and cuts it at four lengths, and runs the command
in a subprocess. Outcomes: ``ok`` (exit 0: the flip hit data the command does not check), ``one line`` (exit 2
or 4 with exactly one ``aca-warp: error:`` line), ``bad`` (anything else: a traceback, a crash, a hang).

``--crafted`` instead feeds crafted files (well-formed HDF5 or TOML built to break a reader: nested, int and array
``scene`` attributes, ``/global/mu`` as strings or a compound type, ``/global/time`` a group, a 2-D ``/patches/x``, a
checkpoint array of another shape, datasets declaring 2^28 or 2^40 rows never written, external and soft links,
TOML scenes and specs nested 20 000 deep or of 64 GiB) to every command that reads them; each
must end with one line, exit 2.

``--formats N`` instead reads every dataset and attribute of the HF run after N random single-bit flips, once as
written (HDF5 ``libver = earliest``, no filters) and once copied with ``libver = "v108"`` (checksummed object
headers and index nodes) and the Fletcher-32 filter on every dataset: how many flips each format detects.

    python scripts/corrupt_files.py --flips 20          # ~10 minutes on the 2-core CPU container
    python scripts/corrupt_files.py --formats 120       # ~2 minutes
    python scripts/corrupt_files.py --crafted           # 48 runs
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from small_scenes import small_lf_scene_toml, small_scene_toml, three_applications

from aca_warp.common.argtypes import int_at_least
from aca_warp.common.errors import AcaError
from aca_warp.common.files import check_output_path

HF_SCENE = small_scene_toml("corrupt", count=40, duration=2.0e-4, sample_dt=1.0e-6, patches=("velocity",))
LF_SCENE = small_lf_scene_toml(
    "corrupt-lf", three_applications(1.0), lf={"p_birth": 1.0}, snapshots={"applications": True}
)

# command: (input, file name in the trial folder, argv)
COMMANDS = {
    "rerun": ("hf", "in.h5", ["rerun", "in.h5", "-o", "out.h5", "--no-progress"]),
    "analyze": ("hf", "in.h5", ["analyze", "in.h5"]),
    "plot": ("hf", "in.h5", ["plot", "in.h5", "-o", "figs", "--only", "global", "spectra", "patch_map"]),
    "hf --resume": ("hf_stopped", "in.h5", ["hf", "--resume", "in.h5", "--no-progress"]),
    "lf --resume": ("lf_stopped", "in.h5", ["lf", "--resume", "in.h5", "--no-progress"]),
    "hf --snapshot": ("lf", "in.h5", ["hf", "in.h5", "--snapshot", "app1_end", "-o", "out.h5", "--duration", "2e-6"]),
    "rerun (LF)": ("lf", "in.h5", ["rerun", "in.h5", "-o", "out.h5", "--no-progress"]),
}


def env() -> dict[str, str]:
    return dict(os.environ)


def build_inputs(
    root: Path, hf_scene: str = HF_SCENE, lf_scene: str = LF_SCENE, hf_interval: float = 5e-5
) -> dict[str, Path]:
    """The four input files from the scene texts ``hf_scene`` and ``lf_scene`` (in this process; the stopped ones by
    an interrupt at the first checkpoint: every ``hf_interval`` [s] of an HF run, 0.2 s of an LF run)."""
    from aca_warp.cli import main
    from aca_warp.hf import runner
    from aca_warp.lf import io as lf_io

    (root / "hf.toml").write_text(hf_scene)
    (root / "lf.toml").write_text(lf_scene)
    out = {k: root / f"{k}.h5" for k in ("hf", "hf_stopped", "lf", "lf_stopped")}
    assert main(["hf", str(root / "hf.toml"), "-o", str(out["hf"]), "--no-progress"]) == 0
    assert main(["lf", str(root / "lf.toml"), "-o", str(out["lf"]), "--no-progress"]) == 0
    real_hf, real_lf = runner.run_hf, lf_io.LFRunWriter.checkpoint

    def hf_once(*args, on_checkpoint=None, **kw):
        def ckpt(c):
            on_checkpoint(c)
            raise KeyboardInterrupt

        return real_hf(*args, on_checkpoint=ckpt, **kw)

    def lf_once(self, sim):
        real_lf(self, sim)
        raise KeyboardInterrupt

    runner.run_hf, lf_io.LFRunWriter.checkpoint = hf_once, lf_once
    try:
        args = ["--no-progress", "--checkpoint-interval"]
        assert main(["hf", str(root / "hf.toml"), "-o", str(out["hf_stopped"]), *args, str(hf_interval)]) == 130
        assert main(["lf", str(root / "lf.toml"), "-o", str(out["lf_stopped"]), *args, "0.2"]) == 130
    finally:
        runner.run_hf, lf_io.LFRunWriter.checkpoint = real_hf, real_lf
    return out


def positions(n: int, k: int, rng: random.Random) -> list[int]:
    head = [p for p in (8, 40, 64, 100, 200, 300, 500, 800, 1000, 1500, 2000, 3000) if p < n]
    rest = [rng.randrange(n) for _ in range(max(k - len(head), 0) * 2 // 3)]
    tail = [n - 1 - rng.randrange(min(n, 4096)) for _ in range(max(k - len(head), 0) - len(rest))]
    return sorted(set(head + rest + tail))


def one(command: str, src: Path, how: str, pos: int, root: Path) -> dict:
    """Damage a copy of ``src`` (flip the bit ``pos % 8`` of byte ``pos``, or cut at ``pos``), run the command."""
    _, name, argv = COMMANDS[command]
    d = root / f"trial-{command.replace(' ', '_')}-{how}-{pos}"
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir()
    data = bytearray(src.read_bytes())
    if how == "flip":
        data[pos] ^= 1 << (pos % 8)
    else:
        del data[pos:]
    (d / name).write_bytes(bytes(data))
    try:
        r = subprocess.run(
            [sys.executable, "-m", "aca_warp.cli", *argv], cwd=d, env=env(), capture_output=True, text=True, timeout=300
        )
        code, err = r.returncode, r.stderr
    except subprocess.TimeoutExpired:
        code, err = "timeout", ""
    lines = [x for x in err.splitlines() if x.strip() and x.startswith(("aca-warp: error", "Traceback", "  File"))]
    if code == 0:
        outcome = "ok"
    elif code in (2, 4) and len(lines) == 1 and lines[0].startswith("aca-warp: error:"):
        outcome = "one line"
    else:
        outcome = "bad"
    shutil.rmtree(d, ignore_errors=True)
    return {"command": command, "how": how, "pos": pos, "exit": code, "outcome": outcome, "last": err.strip()[-300:]}


# Crafted files: a run file (or scene, or spec) that is well-formed HDF5 (TOML) but built to break a reader, each
# with the commands that read it. Every run must end with one ``aca-warp: error:`` line and exit 2.
DEEP = 20_000  # nesting levels of the deeply nested JSON attribute and TOML arrays


def _replace(f: Any, name: str, **kw: Any) -> None:
    """Replace dataset ``name`` of the open file ``f`` by ``create_dataset(name, **kw)``."""
    del f[name]
    f.create_dataset(name, **kw)


def _declared(rows: int) -> Callable[[Any], None]:
    """Every dataset of /global and /patches replaced by a chunked one of the same dtype declaring ``rows`` rows
    (its other dimensions kept), none of them written: a file of about its old size that declares terabytes."""

    def mutate(f: Any) -> None:
        names: list[str] = []
        for g in ("global", "patches"):
            names += [f"{g}/{k}" for k, d in f[g].items() if hasattr(d, "dtype")]
        for name in names:
            d = f[name]
            shape, dtype = (rows, *d.shape[1:]), d.dtype
            chunks = (4096, *(min(n, 64) for n in d.shape[1:]))
            del f[name]
            f.create_dataset(name, shape=shape, maxshape=(None, *shape[1:]), dtype=dtype, chunks=chunks)

    return mutate


def _checkpoint_shape(f: Any) -> None:
    slot = f[f"checkpoint/slot{int(f['checkpoint'].attrs['active'])}/arrays/state"]
    n = slot["u"].shape[0]
    _replace(slot, "u", data=np.zeros(n + 3))


def _external(f: Any) -> None:
    import h5py

    del f["global/mu"]
    f["global/mu"] = h5py.ExternalLink("/etc/hostname", "/mu")


def _soft(f: Any) -> None:
    import h5py

    del f["global/mu"]
    f["global/mu"] = h5py.SoftLink("/global/mu")  # a link to itself


def _mu_as(dtype: Any) -> Callable[[Any], None]:
    def mutate(f: Any) -> None:
        n = f["global/mu"].shape[0]
        _replace(f, "global/mu", data=np.zeros(n, dtype=dtype))

    return mutate


def _time_group(f: Any) -> None:
    del f["global/time"]
    f["global"].create_group("time")


def _patches_x_2d(f: Any) -> None:
    x = f["patches/x"][()]
    _replace(f, "patches/x", data=np.stack([x, x], axis=1))


def _attr(name: str, value: Any) -> Callable[[Any], None]:
    def mutate(f: Any) -> None:
        f.attrs[name] = value

    return mutate


READERS = ("rerun", "analyze", "plot", "hf --resume")
# case: (mutation of the open file, commands); each command reads its own input (COMMANDS: the finished HF run, or
# the one stopped at its first checkpoint for hf --resume) and takes its argv from COMMANDS
CRAFTED: dict[str, tuple[Callable[[Any], None], tuple[str, ...]]] = {
    "nested scene attribute": (_attr("scene", "[" * DEEP + "]" * DEEP), READERS),
    "scene attribute an int": (_attr("scene", 7), READERS),
    "scene attribute an array": (_attr("scene", np.arange(3.0)), READERS),
    "/global/mu as strings": (_mu_as("S8"), ("analyze", "plot", "hf --resume")),
    "/global/mu a compound type": (_mu_as([("a", "f8"), ("b", "i4")]), ("analyze", "plot", "hf --resume")),
    "/global/time a group": (_time_group, ("analyze", "plot", "hf --resume")),
    "2-D /patches/x": (_patches_x_2d, READERS),
    "checkpoint array of another shape": (_checkpoint_shape, ("hf --resume",)),
    "2^28 rows declared": (_declared(2**28), READERS),
    "2^40 rows declared": (_declared(2**40), READERS),
    "external link": (_external, READERS),
    "soft link": (_soft, READERS),
}
# TOML inputs nested 20 000 levels deep, and ones of 64 GiB (a valid start, then zeros: a sparse file), far larger
# than any TOML file read: (file, argv)
DEEP_TOML = "x = " + "[" * DEEP + "]" * DEEP + "\n"
TOML_INPUTS = {
    "hf scene": ("scene.toml", ["hf", "scene.toml", "-o", "out.h5"]),
    "lf scene": ("lf.toml", ["lf", "lf.toml", "-o", "out.h5"]),
    "sweep spec": ("spec.toml", ["sweep", "spec.toml", "-o", "sweep", "--workers", "0"]),
}
OVERSIZED_TOML = 2**36  # bytes
CRAFTED_TOML = {f"{how} {what}": (how, *at) for how in ("nested", "oversized") for what, at in TOML_INPUTS.items()}


def crafted_trials(inputs: dict[str, Path]) -> list[tuple[str, str, Callable[[Path], list[str]]]]:
    """(case, command, prepare) for every crafted case and command: ``prepare(folder)`` writes the crafted input
    into ``folder`` and returns the argv to run there."""
    import h5py

    out = []
    for case, (mutate, commands) in CRAFTED.items():
        for command in commands:

            def prepare(d: Path, mutate: Callable = mutate, command: str = command) -> list[str]:
                src, name, argv = COMMANDS[command]
                shutil.copy(inputs[src], d / name)
                with h5py.File(d / name, "r+") as f:
                    mutate(f)
                return list(argv)

            out.append((case, command, prepare))
    for case, (how, name, argv) in CRAFTED_TOML.items():

        def prepare_toml(d: Path, how: str = how, name: str = name, argv: list[str] = argv) -> list[str]:
            text = HF_SCENE if name == "scene.toml" else LF_SCENE if name == "lf.toml" else ""
            if how == "nested":
                (d / name).write_text(text + ("\n[deep]\n" if name != "spec.toml" else "[sweep]\n") + DEEP_TOML)
            else:
                (d / name).write_text(text + "\n")
                with open(d / name, "r+b") as f:
                    f.truncate(OVERSIZED_TOML)
            return list(argv)

        out.append((case, argv[0], prepare_toml))
    return out


def crafted(inputs: dict[str, Path], root: Path) -> list[dict]:
    """Run every crafted trial in a subprocess; outcomes as :func:`one`'s."""
    results = []
    for case, command, prepare in crafted_trials(inputs):
        d = root / f"crafted-{len(results)}"
        d.mkdir()
        argv = prepare(d)
        r = subprocess.run(
            [sys.executable, "-m", "aca_warp.cli", *argv], cwd=d, env=env(), capture_output=True, text=True, timeout=600
        )
        lines = [x for x in r.stderr.splitlines() if x.strip()]
        one_line = r.returncode == 2 and len(lines) == 1 and lines[0].startswith("aca-warp: error:")
        results.append(
            {"case": case, "command": command, "exit": r.returncode, "outcome": "one line" if one_line else "bad",
             "last": r.stderr.strip()[-300:]}
        )  # fmt: skip
        shutil.rmtree(d, ignore_errors=True)
    return results


READ_ALL = r"""
import h5py, sys, hashlib
try:
    h = hashlib.sha256()
    with h5py.File(sys.argv[1], 'r') as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                h.update(name.encode() + obj[()].tobytes())
        f.visititems(visit)
        for k in sorted(f.attrs):
            h.update(k.encode() + repr(f.attrs[k]).encode())
    print(h.hexdigest())
except Exception as e:
    print('ERROR', type(e).__name__)
"""


def formats(src: Path, root: Path, n: int, rng: random.Random) -> dict:
    """Flips detected when every dataset and attribute is read: the file as written, and a checksummed copy."""
    import h5py

    copy = root / "checksummed.h5"
    with h5py.File(src, "r") as a, h5py.File(copy, "w", libver="v108") as b:
        for k, v in a.attrs.items():
            b.attrs[k] = v

        def visit(name: str, obj: object) -> None:
            if isinstance(obj, h5py.Dataset):
                data = obj[()]
                if data.ndim:
                    chunks = obj.chunks if obj.chunks and obj.maxshape[0] is None else True
                    kw = {"maxshape": obj.maxshape} if obj.maxshape[0] is None else {}
                    b.create_dataset(name, data=data, fletcher32=True, chunks=chunks, **kw)
                else:
                    b.create_dataset(name, data=data)

        a.visititems(visit)
    out = {}
    for label, path in (("as written (libver earliest, no filters)", src), ("v108 + Fletcher-32", copy)):
        ref = subprocess.run([sys.executable, "-c", READ_ALL, str(path)], capture_output=True, text=True).stdout
        data = path.read_bytes()
        counts: Counter = Counter()
        for _ in range(n):
            pos = rng.randrange(len(data))
            b = bytearray(data)
            b[pos] ^= 1 << rng.randrange(8)
            (root / "flipped.h5").write_bytes(bytes(b))
            cmd = [sys.executable, "-c", READ_ALL, str(root / "flipped.h5")]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                counts["crash"] += 1
            elif r.stdout.startswith("ERROR"):
                counts["detected"] += 1
            elif r.stdout == ref:
                counts["no effect"] += 1
            else:
                counts["silent change"] += 1
        out[label] = {"bytes": len(data), **counts}
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--flips", type=int_at_least(1), default=20, help="bit flips per command (default 20)")
    p.add_argument("--commands", default=",".join(COMMANDS), help="comma-separated subset of: " + ", ".join(COMMANDS))
    p.add_argument(
        "--formats", type=int_at_least(0), default=0, metavar="N", help="compare detection of N flips by format"
    )
    p.add_argument("--crafted", action="store_true", help="run the crafted files instead of flips and cuts")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--jobs", type=int_at_least(1), default=2, help="commands run at once (default 2)")
    p.add_argument("--json", type=Path, help="write the results here")
    args = p.parse_args(argv)
    unknown = [c for c in args.commands.split(",") if c not in COMMANDS]
    if unknown:
        p.error(f"--commands: unknown {', '.join(map(repr, unknown))}; choose from {', '.join(COMMANDS)}")
    if args.json is not None:
        try:
            check_output_path(args.json, overwrite=True)
        except AcaError as e:
            p.error(str(e))
    rng = random.Random(args.seed)
    root = Path(tempfile.mkdtemp(prefix="aca-warp-corrupt-"))
    try:
        inputs = build_inputs(root)
        if args.crafted:
            res = crafted(inputs, root)
            for r in res:
                print(f"| {r['case']} | {r['command']} | {r['exit']} | {r['outcome']} |")
                if r["outcome"] == "bad":
                    print(f"BAD {r['case']} / {r['command']}: {r['last']}")
            if args.json:
                args.json.write_text(json.dumps(res, indent=1))
            return 1 if any(r["outcome"] == "bad" for r in res) else 0
        if args.formats:
            res = formats(inputs["hf"], root, args.formats, rng)
            for label, c in res.items():
                print(f"{label}: {c}")
            if args.json:
                args.json.write_text(json.dumps(res, indent=1))
            return 0
        jobs = []
        for command in args.commands.split(","):
            src = inputs[COMMANDS[command][0]]
            n = src.stat().st_size
            jobs += [(command, src, "flip", q, root) for q in positions(n, args.flips, rng)]
            jobs += [(command, src, "cut", q, root) for q in sorted({96, 2000, n // 2, n - 100})]
        with ThreadPoolExecutor(args.jobs) as ex:
            results = list(ex.map(lambda j: one(*j), jobs))
        table = Counter((r["command"], r["outcome"]) for r in results)
        print("| command | runs | exit 0 | one line | bad |\n|---|---|---|---|---|")
        for command in dict.fromkeys(r["command"] for r in results):
            runs = sum(v for (c, _), v in table.items() if c == command)
            row = [table[(command, o)] for o in ("ok", "one line", "bad")]
            print(f"| {command} | {runs} | {row[0]} | {row[1]} | {row[2]} |")
        for r in results:
            if r["outcome"] == "bad":
                print(f"BAD {r['command']} {r['how']} at {r['pos']}: exit {r['exit']}: {r['last']}")
        if args.json:
            args.json.write_text(json.dumps(results, indent=1))
        return 1 if any(r["outcome"] == "bad" for r in results) else 0
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
