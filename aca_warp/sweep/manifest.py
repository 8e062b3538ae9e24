"""The sweep directory: its manifest (written only by the client), the record of a sweep call, and reading results.

:func:`prepare_dir` creates or reopens a directory and verifies every shard's state against its file;
:class:`_Book` records what a sweep call does (:data:`SHARD_STATES`; docs/sweeps.md, "Manifest states") and writes
the manifest atomically at every change; :func:`load_sweep` reads the finished shards into one dict.
"""

from __future__ import annotations

import json
import os
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.sweep.shard import shard_finished, shard_name
from aca_warp.sweep.spec import FORMAT, SweepError, SweepSpec, base_file, stored_crossing

MANIFEST = "manifest.json"
# the states of a shard in the manifest (docs/sweeps.md, "Manifest states")
SHARD_STATES = ("pending", "queued", "done", "fault", "failed", "interrupted")


# ------------------------------------------------------------------------------------------- manifest


def _write_json(path: Path, doc: dict) -> None:
    """Write ``doc`` to ``path`` atomically (a temporary file, created exclusively and never through a link, then a
    rename); a full device keeps the old one."""
    from aca_warp.common.links import create_new
    from aca_warp.common.storage import storage_errno, storage_error

    tmp = path.with_name(path.name + ".tmp")
    try:
        with os.fdopen(create_new(tmp, "temporary manifest"), "w") as fh:
            fh.write(json.dumps(doc, indent=1, default=str))
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        code = storage_errno(e)
        if code is None:
            raise
        raise storage_error(code, path, "it keeps its previous state; make room and run the sweep again") from None


def read_manifest(out_dir: str | Path) -> dict | None:
    """The manifest of a sweep directory, or None when there is none."""
    p = Path(out_dir) / MANIFEST
    if not p.is_file():
        return None
    from aca_warp.common.bounds import check_nesting
    from aca_warp.common.errors import SceneError

    try:
        text = p.read_text()
        check_nesting(text, str(p))
        return json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError, SceneError) as e:
        raise SweepError(f"{p} is not a sweep manifest ({e}); remove it or pass --overwrite") from None


_FLAGS = {  # the run settings a sweep command's options set
    "precision": "--precision",
    "dt": "--dt",
    "duration": "--duration",
    "integrator": "--integrator",
    "growth_dt": "--growth-dt",
    "crossing": "--crossing",
}


def _run_changes(old: dict | None, spec: SweepSpec) -> str:
    """What differs between the sweep of manifest ``old`` and ``spec``, as a clause of the refusal: the spec's other
    parts (:func:`_spec_changes`) and the run settings, with the options that continue it where only what options
    set differs (the run settings and the shard size: ``--precision fp64`` for a sweep begun at another default
    precision, ``--dt`` for another default step, ``--growth-dt scene`` for one whose growth events came at the
    scenes' interval, ``--crossing point`` for one begun when that was every sweep's treatment, ``--duration``,
    ``--shard-size`` for overrides left out of the second call), each value as stored (every digit: a rounded one
    would be another sweep again); where nothing the manifest records differs, that a file the spec names changed; ""
    where ``old`` records none of it."""
    if not isinstance(old, dict) or not isinstance(old.get("run"), dict):
        return ""
    before, now = old["run"], spec.run_settings()
    others = _spec_changes(old, spec)
    shard_size = [f"--shard-size {old['shard_size']}"] if old.get("shard_size") != spec.shard_size else []
    keys = sorted(k for k in before.keys() | now.keys() if before.get(k) != now.get(k))
    if not keys:
        if others:
            hint = f" (to continue it: {shard_size[0]})" if shard_size and len(others) == 1 else ""
            return f": its {', '.join(others)} {_differ(others)}{hint}"
        base = base_file(spec.doc)
        if base:
            return f": the spec is the same, so its base scene file {base} (or a file that names) has changed since"
        return (
            ": the spec is the same, so the scene it builds has changed since (a patch file it names, or this "
            "aca_warp's presets or scene defaults)"
        )
    was = dict(before)  # each setting as an option gives it: a spacing left out is the scenes' own clock
    if "growth_dt" not in was and spec.base.growth is not None:
        was["growth_dt"] = "scene"
    was["crossing"] = stored_crossing(was)
    changed = ", ".join(f"{k} {before.get(k, 'unset')} there, {now.get(k, 'unset')} here" for k in keys)
    again = [f"{_FLAGS[k]} {was[k]}" for k in keys if k in _FLAGS and was.get(k) is not None]
    settable = len(again) == len(keys) and len(others) == len(shard_size)
    hint = f" (to continue it: {' '.join(again + shard_size)})" if settable else ""
    also = f"; its {', '.join(others)} {_differ(others)} too" if others else ""
    return f": its run settings differ ({changed}){hint}{also}"


def _differ(parts: list[str]) -> str:
    """The verb for ``parts`` (one or more parts of a spec, in words)."""
    return "differs" if len(parts) == 1 else "differ"


def _spec_changes(old: dict, spec: SweepSpec) -> list[str]:
    """The parts of the spec besides the run settings in which the sweep of manifest ``old`` differs from ``spec``:
    its parameters, base scene (the preset or file named, and the tables that change it), mode, packing, shard size
    and pad count, in words."""
    normal = lambda x: json.loads(json.dumps(x, default=str))  # noqa: E731  (as the manifest stored it)
    was, now = normal(old.get("spec") or {}), normal(spec.doc)
    sw_was, sw_now = was.get("sweep", {}), now.get("sweep", {})
    parts = [
        words
        for differs, words in (
            (was.get("parameters") != now.get("parameters"), "parameters"),
            (sw_was.get("base") != sw_now.get("base") or was.get("base") != now.get("base"), "base scene"),
            (sw_was.get("mode") != sw_now.get("mode"), "mode"),
            (sw_was.get("pack") != sw_now.get("pack"), "packing"),
        )
        if differs
    ]
    if old.get("shard_size") != spec.shard_size:
        parts.append(f"shard size ({old.get('shard_size')} there, {spec.shard_size} here)")
    if old.get("pads") != spec.pad_count:
        parts.append(f"pad count ({old.get('pads')} there, {spec.pad_count} here)")
    return parts


_SHARD_FILE = re.compile(r"shard-(\d{5})\.h5")
_PAD_FILE = re.compile(r"shard-\d{5}_pad\d+\.h5")  # a pad that analyze/plot --pad took out of a shard


def _state_of(d: Path, spec: SweepSpec, index: int, patch_data: str | None) -> str | None:
    """:func:`~aca_warp.sweep.shard.shard_finished` of shard ``index`` of ``spec`` in folder ``d``, made over the
    patches of digest ``patch_data``."""
    return shard_finished(d / shard_name(index), spec.hash, *spec.shard_range(index), patch_data)


def _lost_manifest(d: Path, spec: SweepSpec, stray: list[Path]) -> bool:
    """Whether the shard files of ``d``, a folder without a manifest, are finished shards of ``spec`` itself (the
    spec's hash, pad range and patch digest; besides them only pads taken out of shards): its manifest was lost, and
    the sweep continues from them."""
    shards = [p for p in stray if not _PAD_FILE.fullmatch(p.name)]
    for p in shards:
        m = _SHARD_FILE.fullmatch(p.name)
        if m is None or int(m.group(1)) >= spec.shard_count:  # an unfinished one (.partial), or another sweep's
            return False
        if _state_of(d, spec, int(m.group(1)), spec.patch_data) is None:
            return False
    return bool(shards)


def finished_shards(spec: SweepSpec, out_dir: str | Path) -> list[int] | None:
    """Every shard index of ``spec`` when each is finished in ``out_dir`` as the folder stood when read, else None:
    its manifest names this spec over the same patches, and records every shard ``done`` or ``fault`` as its file
    verifies it (:func:`shard_finished`; a shard whose file finished after its client died is recorded otherwise,
    and only :func:`prepare_dir` can record it, which :func:`load_sweep` needs). Reads only: for a folder that takes
    no new file, where :func:`prepare_dir` cannot run."""
    d = Path(out_dir)
    old = read_manifest(d)
    if old is None or old.get("spec_hash") != spec.hash:
        return None
    patch_data = old.get("patch_data")
    shards = old.get("shards", [])
    if (patch_data is not None and patch_data != spec.patch_data) or len(shards) != spec.shard_count:
        return None
    for i, entry in enumerate(shards):
        state = _state_of(d, spec, i, patch_data)
        if state is None or entry.get("state") != state:
            return None
    return list(range(spec.shard_count))


def prepare_dir(spec: SweepSpec, out_dir: str | Path, *, overwrite: bool = False) -> dict:
    """Create or reopen the sweep directory; returns the manifest with every shard's verified state.

    A directory that holds another sweep (different spec hash) is refused unless ``overwrite``, which removes
    that sweep's manifest and shard files (nothing else). The caller holds the directory's lock
    (:func:`run_sweep`); a shard still being written by a worker of an earlier sweep is refused.
    """
    from aca_warp.common.files import locked_output

    d = Path(out_dir)
    if d.exists() and not d.is_dir():
        raise SweepError(f"{d} exists and is not a folder")
    d.mkdir(parents=True, exist_ok=True)
    old = read_manifest(d)
    stray = sorted(d.glob("shard-*.h5*"))
    if old is None and _lost_manifest(d, spec, stray):
        stray = []  # this sweep's own finished shards, its manifest lost: they are verified and kept below
    recorded = (old or {}).get("patch_data")  # absent in the folders of sweeps begun before it was recorded
    other_patches = recorded is not None and recorded != spec.patch_data and old.get("spec_hash") == spec.hash
    if (old is not None and old.get("spec_hash") != spec.hash) or (old is None and stray) or other_patches:
        if not overwrite:
            if other_patches:
                raise SweepError(
                    f"{d} holds this sweep begun over other patches: its patch file {spec.base.patches.source} has "
                    f"changed since (the patches' SHA-256 {str(recorded)[:12]} there, {str(spec.patch_data)[:12]} "
                    "here); restore the file to continue the sweep, pass --overwrite to start it over, or choose "
                    "another output directory"
                )
            if old is not None:
                what = f"a different sweep ({old.get('name', '?')!r}, spec hash {str(old.get('spec_hash'))[:12]})"
            else:
                what = f"{len(stray)} shard file(s) without a manifest"
            raise SweepError(
                f"{d} holds {what}, not this spec (hash {spec.hash[:12]}){_run_changes(old, spec)}; "
                "pass --overwrite to replace it, or choose another output directory"
            )
        for p in stray:
            with locked_output(d / p.name.removesuffix(".partial"), what="it belongs to a sweep that still runs"):
                p.unlink(missing_ok=True)
        (d / MANIFEST).unlink(missing_ok=True)
        old = None
    # the digest of a patch file's patches: recorded by a new folder, kept absent by one begun without it (its
    # finished shards were made over patches nobody recorded)
    patch_data = spec.patch_data if old is None else old.get("patch_data")
    shards = []
    for i in range(spec.shard_count):
        a, b = spec.shard_range(i)
        prev = (old or {}).get("shards", [])
        entry = dict(prev[i]) if i < len(prev) else {}
        entry.update(index=i, file=shard_name(i), pad_start=a, pad_stop=b)
        verified = _state_of(d, spec, i, patch_data)
        if verified is None:
            entry["state"] = "pending"
            with locked_output(d / shard_name(i), what="a worker of an earlier sweep still runs; stop it first"):
                (d / (shard_name(i) + ".partial")).unlink(missing_ok=True)
        elif entry.get("state") != verified:
            entry["state"] = verified  # the worker finished; the client died before recording it
        shards.append(entry)
    manifest = {
        "format": FORMAT,
        "name": spec.name,
        "spec_hash": spec.hash,
        "spec": spec.doc,
        "base_dir": str(spec.base_dir),
        "pads": spec.pad_count,
        "shard_size": spec.shard_size,
        "pad_order": "spec" if spec.order is None else "patch_count",
        "parameters": list(spec.parameters),
        "run": spec.run_settings(),
        **({"patch_data": patch_data} if patch_data is not None else {}),
        "shards": shards,
    }
    _write_json(d / MANIFEST, manifest)
    return manifest


# ------------------------------------------------------------------------------------------ sweep calls


@dataclass
class SweepResult:
    """What a sweep call did.

    Attributes:
        out_dir: The sweep directory.
        ran: Indices of the shards run by this call, ascending.
        skipped: Indices of the shards found finished and skipped.
        failed: Shard index -> error text, for shards that raised (state ``failed``; rerun to retry).
        faults: Indices of shards whose run stopped on a non-finite value (state ``fault``).
        wall_time: Wall time of the whole call, cluster start included [s].
        patch_steps: Patch-steps done by this call.
        workers: Number of workers used (0: this process).
        summaries: The summaries of the shards run (:func:`run_shard`), in the order they finished.
        interrupted: Shards stopped by an interrupt (state ``interrupted``; set before the interrupt is raised).
    """

    out_dir: Path
    ran: list[int]
    skipped: list[int]
    failed: dict[int, str]
    faults: list[int]
    wall_time: float
    patch_steps: int
    workers: int
    summaries: list[dict] = field(default_factory=list)
    interrupted: list[int] = field(default_factory=list)


def _one_line(e: BaseException) -> str:
    """``Type: first line of the message`` of an error, for the manifest and the log."""
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0]}" if text else type(e).__name__


class _Book:
    """The client's record of a sweep call: the manifest (written atomically at every change) and the result."""

    def __init__(self, spec: SweepSpec, out: Path, manifest: dict, say: Callable[[str], None]) -> None:
        self.out, self.manifest, self.say = out, manifest, say
        self.spec_hash = spec.hash
        self.patch_data = manifest.get("patch_data")
        shards = manifest["shards"]
        self.todo = [s["index"] for s in shards if s["state"] not in ("done", "fault")]
        skipped = [s["index"] for s in shards if s["state"] in ("done", "fault")]
        if skipped:
            say(f"{len(skipped)} of {spec.shard_count} shard(s) already finished, skipped")
        self.result = SweepResult(out, [], skipped, {}, [], 0.0, 0, 0)
        self.recorded: set[int] = set()

    def save(self) -> None:
        _write_json(self.out / MANIFEST, self.manifest)

    def queued(self, indices: list[int]) -> None:
        for i in indices:
            self.manifest["shards"][i]["state"] = "queued"
        self.save()

    def done(self, index: int, summary: dict) -> None:
        ran_over = summary.get("patch_data")
        if self.patch_data is not None and ran_over != self.patch_data:  # the file was rewritten while the sweep ran
            (self.out / summary["file"]).unlink(missing_ok=True)  # not the sweep's data: no pad is taken out of it
            self.failed(
                index,
                f"SweepError: shard {index} ran over other patches than the sweep began with (the patch file's "
                f"SHA-256 {str(ran_over)[:12]}, the sweep's {self.patch_data[:12]}): the file changed while the sweep "
                "ran; the shard's file was removed",
            )
            return
        entry = self.manifest["shards"][index]
        entry.pop("error", None)
        entry.update({k: v for k, v in summary.items() if k not in ("index", "patch_data")})
        self.recorded.add(index)
        self.result.ran.append(index)
        self.result.patch_steps += int(summary["patch_steps"])
        self.result.summaries.append(summary)
        if summary["state"] == "fault":
            self.result.faults.append(index)
        kernel = summary.get("timings", {}).get("kernel") or summary["wall_time"]
        self.say(
            f"shard {index}: {summary['pads']} pads, {summary['state']} on {summary['device_name']}, "
            f"{summary['patch_steps'] / max(kernel, 1e-12):.3g} patch-steps/s"
        )
        self.save()

    def failed(self, index: int, error: str) -> None:
        entry = self.manifest["shards"][index]
        entry["state"] = "failed"
        entry["error"] = error
        self.recorded.add(index)
        self.result.failed[index] = error
        self.say(f"shard {index}: failed: {error}")
        self.save()

    def stopped(self, started: set[int]) -> list[int]:
        """The sweep stops: shards of this call not recorded are ``interrupted`` (begun), ``pending`` (not begun) or,
        when their file says so, ``done``/``fault`` (a worker finished it as the stop came); returns the interrupted
        ones. The manifest is written even if a second signal comes (best effort)."""
        hit = []
        for i in self.todo:
            if i in self.recorded:
                continue
            entry = self.manifest["shards"][i]
            finished = shard_finished(
                self.out / entry["file"], self.spec_hash, entry["pad_start"], entry["pad_stop"], self.patch_data
            )
            if finished is not None:
                entry["state"] = finished
                self.result.skipped.append(i)  # finished, but its summary was not received: not counted as run
            elif i in started:
                entry["state"] = "interrupted"
                hit.append(i)
            else:
                entry["state"] = "pending"
        self.result.interrupted = hit
        self.save()
        return hit


def load_sweep(out_dir: str | Path) -> dict[str, Any]:
    """Read every finished shard of a sweep directory into one dict, pads in global order (rows placed by each
    file's ``/pads/index``: shards of pads packed by size hold pads from all over the sweep).

    Keys: ``time`` (samples,) [s] of the shard with the most samples, the global outputs (pads, samples),
    ``parameters`` (key -> (pads,)), ``pad_index`` (pads,): the global index of each row, ``units`` (the time's,
    every output's and every parameter's, as the shards' ``unit`` attributes give them), ``complete``: whether every
    pad of the sweep is there, ``manifest``. Shards with different sample counts (a fault) are padded with NaN. A
    sweep not yet finished gives the pads of its finished shards only (row k is then not pad k: read
    ``pad_index``), and says so in a :class:`UserWarning`.
    """
    from aca_warp.common.errors import SceneError
    from aca_warp.common.files import open_h5
    from aca_warp.hf.recorder import GLOBAL_NAMES

    d = Path(out_dir)
    if not d.exists():
        raise SweepError(f"sweep directory {d} does not exist")
    manifest = read_manifest(d)
    if manifest is None:
        raise SweepError(f"{d} has no {MANIFEST}: not a sweep directory")
    parts: list[dict] = []
    for s in manifest["shards"]:
        if s["state"] not in ("done", "fault"):
            continue
        try:
            with open_h5(d / s["file"], "shard", text=("parameters",)) as f:  # links, declared sizes checked first
                parts.append(
                    {
                        "time": f["global/time"][()],
                        **{k: f["global"][k][()] for k in GLOBAL_NAMES},
                        "parameters": {k: v[()] for k, v in f["parameters"].items()},
                        "pad_index": f["pads/index"][()],
                        "units": {
                            k: str(v.attrs.get("unit", "")) for g in ("global", "parameters") for k, v in f[g].items()
                        },
                    }
                )
        except SceneError as e:
            if not (d / s["file"]).exists():
                raise SweepError(
                    f"shard {d / s['file']} is missing (its manifest has it finished): run the sweep again to run it "
                    "again"
                ) from None
            raise SweepError(f"{e}; remove it and rerun the sweep") from None
        except (OSError, RuntimeError, KeyError, ValueError, TypeError) as e:  # missing, truncated or damaged
            raise SweepError(
                f"cannot read shard {d / s['file']} ({type(e).__name__}: {e}); remove it and rerun the sweep"
            ) from None
    if not parts:
        raise SweepError(f"{d}: no finished shard yet")
    width = max(len(p["time"]) for p in parts)

    def pad_cols(a: np.ndarray) -> np.ndarray:
        return a if a.shape[1] == width else np.pad(a, ((0, 0), (0, width - a.shape[1])), constant_values=np.nan)

    order = np.argsort(np.concatenate([p["pad_index"] for p in parts]), kind="stable")
    out: dict[str, Any] = {"time": max((p["time"] for p in parts), key=len), "manifest": manifest}
    for k in GLOBAL_NAMES:
        out[k] = np.concatenate([pad_cols(p[k]) for p in parts])[order]
    out["parameters"] = {k: np.concatenate([p["parameters"][k] for p in parts])[order] for k in parts[0]["parameters"]}
    out["pad_index"] = np.concatenate([p["pad_index"] for p in parts])[order]
    out["units"] = parts[0]["units"]
    pads = manifest.get("pads", len(out["pad_index"]))
    out["complete"] = len(out["pad_index"]) == pads
    if not out["complete"]:
        left = [str(s["index"]) for s in manifest["shards"] if s["state"] not in ("done", "fault")]
        named = ", ".join(left[:8]) + (f", … ({len(left)} shards)" if len(left) > 8 else "")
        warnings.warn(
            f"{d} holds {len(out['pad_index'])} of its {pads} pads: shard(s) {named} not finished (run the sweep "
            "again to finish them); row k is the pad pad_index[k]",
            stacklevel=2,
        )
    return out
