"""The size of HF run files on disk against the free-space estimate of their run plan.

Runs a few small CPU runs (global samples only; per-patch histories of 40 and 100 patches, narrower and wider than
a history chunk's 64 columns; a patch window with decimation; checkpoints) and prints, per run, the recorded
samples (``RunPlan.output_bytes``, what the free-space check asked for before), the estimate of the file on disk
(``RunPlan.file_bytes``, what it asks for now) and the file's size when the run ends. The estimate must not be
below the file.

    python scripts/file_size.py            # ~1 minute on the 2-core CPU container
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

SCENE = """
[scene]
name = "size"
[load]
normal_force = 20.0
[disc]
sliding_speed = 10.0
[patches]
count = {count}
area_min = 2.0e-8
area_max = 8.0e-8
height = 3.0e-6
seed = 4
[record]
sample_dt = {sample_dt}
patches = {patches}
{window}
[run]
duration = {duration}
"""

WINDOW = "window = [5e-5, 1.5e-4]\ndecimation = 3"
# name: (patches, sample interval [s], per-patch histories, window and decimation, duration [s], checkpoint [s])
CASES = {
    "global samples only": (40, 1e-7, [], "", 2e-4, None),
    "40 patches, velocity": (40, 1e-7, ["velocity"], "", 2e-4, None),
    "40 patches, velocity + displacement": (40, 5e-7, ["velocity", "displacement"], "", 1e-3, None),
    "100 patches, velocity, checkpoints": (100, 1e-7, ["velocity"], "", 2e-4, 5e-5),
    "100 patches, window, decimation 3": (100, 1e-7, ["velocity"], WINDOW, 2e-4, None),
    "1000 patches, velocity, 200 samples": (1000, 1e-6, ["velocity"], "", 2e-4, None),
}  # fmt: skip


def measure(root: Path) -> list[dict]:
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.runner import plan_run, run_scene
    from aca_warp.scene import load_scene

    out = []
    for name, (count, sample_dt, patches, window, duration, ckpt) in CASES.items():
        toml = root / "s.toml"
        toml.write_text(
            SCENE.format(count=count, sample_dt=sample_dt, patches=patches, window=window, duration=duration)
        )
        scene = load_scene(toml)
        options = RunOptions(duration=duration, checkpoint_interval=ckpt)
        plan = plan_run(scene, options)
        path = root / f"run-{len(out)}.h5"
        run_scene(scene, path, options)
        out.append(
            {"case": name, "recorded": plan.output_bytes, "estimate": plan.file_bytes, "file": path.stat().st_size}
        )
    return out


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="aca-warp-size-") as d:
        rows = measure(Path(d))
    print("| run | recorded samples | estimate (file_bytes) | file on disk | estimate / file |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['case']} | {r['recorded'] / 1e3:.0f} kB | {r['estimate'] / 1e3:.0f} kB | {r['file'] / 1e3:.0f} kB "
            f"| {r['estimate'] / r['file']:.2f} |"
        )
    return 0 if all(r["estimate"] >= r["file"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
