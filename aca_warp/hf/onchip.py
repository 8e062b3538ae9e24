"""On-chip HF engine: one thread block (or a thread-block cluster) per pad advances many ``strang`` steps per launch.

The pad's displacement (double-buffered), staggered velocity and spring-force cache live in shared memory for the
whole launch; after every sample interval each warp stores its part of the global outputs' sums (μ, torque, friction
radius, Σu̇, Σ|u̇|) and the owning threads the per-patch histories, and after the launch two kernels make the rows
(one thread per sample and pad) and give the watchdog each pad's first fault (one thread per pad) from the parts
(:mod:`aca_warp.kernels.hf_onchip`, ``pad_samples_kernel``). Patch growth
(varying-area scenes) runs in the kernel too. The launch layout (threads, cluster, tiles) and the engine choice are in
:mod:`aca_warp.hf.onchip_layout`; the run loop around the launches is :func:`aca_warp.hf.loop.run_hf`.

Same arithmetic as the general engine: on the CPU (where Warp runs a block as one thread) μ(t) and the final
(u, u̇) are bit-identical to it; on CUDA the sums of the global outputs are taken in a different order
and the CUDA compiler may contract differently, so results agree to rounding.
"""

from __future__ import annotations

import math
from typing import Any

import warp as wp

from aca_warp.common.devices import load_kernels
from aca_warp.common.errors import SceneError
from aca_warp.hf.engine import EngineSetup, Progress, fault_cause, run_stages
from aca_warp.hf.model import PadModel
from aca_warp.hf.onchip_layout import (
    MAX_CLUSTER,
    block_config,
    choose_engine,
    default_cluster,
    grown_tiles,
    itemsize,
    kernel_tiles,
    unsupported,
    widen_for_csr,
)
from aca_warp.hf.recorder import Recorder
from aca_warp.hf.solver import HFSolver, grown_arrays, growth_events
from aca_warp.hf.state import HFState
from aca_warp.kernels.hf_onchip import PART, Verdict, onchip_kernel, pad_samples_kernel

__all__ = ["OnchipEngine", "choose_engine"]

_PATCH_BUFFER_BYTES = 256 * 2**20  # cap of the per-patch history buffers of one launch
_PARTS_BYTES = 256 * 2**20  # cap of the warps' parts of a launch's samples (OnchipEngine.parts; at least one sample)
_STEPS_PER_LAUNCH = 20_000  # default: sample intervals per launch fill about this many steps
# on the CPU (a pad's block is one thread, ~1e7 patch-steps/s) also at most about this many patch-steps, about a
# second: progress, Ctrl-C and checkpoints stay timely on large batches
_CPU_PATCH_STEPS_PER_LAUNCH = 10_000_000


def cluster_size(model: PadModel, cluster: int | None, split_fits_csr: bool | None = None) -> int:
    """Blocks per pad: ``cluster`` checked, or :func:`default_cluster` on CUDA sm_90+ (else 1). ``split_fits_csr``
    None (the strang kernel, which keeps a block's neighbour lists on chip where they fit): the rule's last case from
    whether only a pad split in two keeps them in shared memory, and a batch of few pads widened until they do
    (:func:`widen_for_csr`); a bool (the adaptive kernel): that case as given, no widening."""
    dev = model.device
    if cluster is None:
        cluster = 1
        if dev.is_cuda and dev.arch >= 90:
            strang = split_fits_csr is None
            if strang:
                split_fits_csr = not block_config(model, 1)[2] and block_config(model, 2)[2]
            cluster = default_cluster(model.pad_count, dev.sm_count, split_fits_csr)
            if strang:
                cluster = widen_for_csr(cluster, lambda k: block_config(model, k)[2])
    if not 1 <= cluster <= MAX_CLUSTER:
        raise SceneError(f"cluster must be in [1, {MAX_CLUSTER}] blocks per pad, got {cluster}")
    if cluster > 1 and (dev.is_cpu or dev.arch < 90):
        raise SceneError(f"a cluster of {cluster} blocks per pad needs a CUDA device of compute capability 9.0+")
    return cluster


class OnchipLaunches:
    """What both on-chip engines share: sample 0 from the general recorder's kernels, the kernels' modules loaded
    before the run, the ``started`` counter of the checkpoints, and the recorder rows of a launch."""

    capture_time = 0.0
    started = False
    spl: int  # sample intervals per launch at most
    n_samples: int
    state: HFState
    model: PadModel
    recorder: Recorder
    solver: HFSolver
    kernel: wp.Kernel
    blocks_per_pad: int
    block_dim: int
    extra_kernels: tuple[wp.Kernel, ...] = ()  # loaded with ``kernel`` before the run

    def begin(self, resume: dict[str, int] | None) -> None:
        kernels = [(self.kernel, self.block_dim), *self.extra_kernels, *self.solver.kernels(stepping=False)]
        load_kernels(kernels, self.model.device)
        if resume is None:
            self.recorder.launch(self.state.u, self.state.v, conditional=False)  # sample 0: the initial state
        else:
            self.started = bool(resume.get("started", 0))

    def counters(self) -> dict[str, int]:
        return {"started": int(self.started)}

    def launch_rows(self, p: Progress, most: int) -> tuple[int, int, int, int]:
        """(sample intervals of the next launch after ``p``, at most ``most``; the recorder's next sample index,
        globals row and per-patch row)."""
        return min(self.spl, self.n_samples - p.samples, most), *self.recorder.kernel_rows()

    def launch_kernel(self, inputs: list) -> None:
        """Launch the kernel on every pad (``blocks_per_pad`` blocks of ``block_dim`` threads each)."""
        m = self.model
        wp.launch_tiled(
            self.kernel,
            dim=[m.pad_count * self.blocks_per_pad],
            block_dim=self.block_dim,
            device=m.device,
            inputs=inputs,
        )


class OnchipEngine(OnchipLaunches):
    """The on-chip ``strang`` kernel (:class:`~aca_warp.hf.loop.Engine`); tuning from :class:`EngineTuning`.

    ``block_dim``: threads per block (default :func:`~aca_warp.hf.onchip_layout.default_block`); ``csr_shared``:
    neighbour lists in shared memory (default: when they fit); ``samples_per_launch``: sample intervals per launch
    (default: about 20k steps); ``cluster``: blocks per pad, 1–16 (CUDA sm_90+; above 8 a "non-portable" size,
    refused where the device cannot launch it); ``ablate``: profiling only. CUDA fast math is a run option
    (``RunOptions.fast_math``). On the CPU a block is one thread unless ``wp.config.enable_cpu_blocks`` is set (Warp's
    cooperative CPU fibers, used by the tests).
    """

    def __init__(self, setup: EngineSetup) -> None:
        model, state, options, record = setup.model, setup.state, setup.options, setup.record
        n_samples, tuning = setup.n_samples, setup.tuning
        why = unsupported(model, options.integrator)
        if why is not None:
            raise SceneError(f"on-chip engine: {why}")
        self.model, self.state, self.record, self.n_samples = model, state, record, n_samples
        self.solver = HFSolver.for_run(model, options, setup.estimate)
        self.estimate = self.solver.estimate
        self.sps = max(1, math.ceil(record.sample_dt / self.solver.dt - 1e-9))
        self.h = record.sample_dt / self.sps
        self.blocks_per_pad = cluster = cluster_size(model, tuning.cluster)
        self.block_dim, self.threads, csr_shared = block_config(model, cluster, tuning.block_dim, tuning.csr_shared)
        # a block's parts of a sample: one per warp (on the CPU, where a block's threads are not warps, per thread)
        self.warps = self.threads if model.device.is_cpu else math.ceil(self.threads / 32)
        self.spl = self._samples_per_launch(tuning.samples_per_launch)
        self.recorder = Recorder(model, record, self.spl + 1, n_samples)
        blocks = model.pad_count * cluster
        self.parts = wp.empty((self.spl, blocks, self.warps, PART), dtype=wp.float64, device=model.device)
        self.verdicts = wp.empty((self.spl, model.pad_count), dtype=Verdict, device=model.device)
        self.kernel = onchip_kernel(
            model.dtype,
            *kernel_tiles(model, cluster, self.threads),
            bool(csr_shared),
            self.block_dim,
            frozenset(tuning.ablate),
            options.fast_math,
            "pad_growth" in model.arrays,
            cluster,
            min(self.threads, 32),
            grown_tiles(model, cluster),
            bool(self.solver.crossing),
        )
        self.extra_kernels = pad_samples_kernel(model.dtype)  # after each launch: the rows and faults from the parts
        dev = model.device
        if cluster > 1 and wp.get_cuda_max_cluster_dim(self.kernel, dev, block_dim=self.block_dim) < cluster:
            raise SceneError(
                f"{dev.name} cannot launch a cluster of {cluster} blocks of {self.block_dim} threads per pad"
            )
        self.stages = run_stages(model, self.recorder, "strang:onchip")
        self.kernel_model = self._kernel_model()
        self.cause = fault_cause(self.estimate, "strang", self.h)
        self.solver.prepare(state)

    def _samples_per_launch(self, asked: int | None) -> int:
        """Sample intervals per launch: ``asked`` or ~20k steps (on the CPU at most ~1e7 patch-steps), at most the run,
        the history buffer cap and the cap of the samples' parts."""
        steps = _STEPS_PER_LAUNCH
        if self.model.device.is_cpu:
            steps = min(steps, _CPU_PATCH_STEPS_PER_LAUNCH // self.model.patch_count)
        spl = max(1, steps // self.sps) if asked is None else asked
        part_row = self.model.pad_count * self.blocks_per_pad * self.warps * PART * 8  # bytes of a sample's parts
        spl = max(1, min(spl, self.n_samples, _PARTS_BYTES // part_row))
        probe = Recorder(self.model, self.record, 1, self.n_samples)
        per_row = (int(probe.want_v) + int(probe.want_u)) * self.model.patch_count * itemsize(self.model)
        return max(1, min(spl, _PATCH_BUFFER_BYTES // per_row)) if per_row else spl

    def _kernel_model(self) -> Any:
        """The kernel's model struct, for a growing model with the increment per event of step h."""
        m = self.model
        if "pad_growth" in m.arrays:
            self.growth_every, per_event = growth_events(m, self.h, self.solver.growth_dt)
            return m.struct(per_event)
        self.growth_every = 1  # the growth fields are not read
        return m.struct()

    # -- the Engine protocol

    def saved(self) -> dict[str, wp.array]:
        return grown_arrays(self.model)

    def advance(self, p: Progress, most: int) -> Progress:
        reps, k_next, rows, prows = self.launch_rows(p, most)
        self._launch(p.samples, reps, k_next, rows, prows)
        self.started = True
        self.recorder.kernel_recorded(k_next, rows, prows, reps)
        samples = p.samples + reps
        return Progress(samples, samples * self.sps, 0, samples * self.record.sample_dt, samples >= self.n_samples)

    def step_used(self) -> float:
        return self.h

    def finish(self) -> None:
        if self.started:
            self.solver.finish(self.state, self.h)

    def _launch(self, done: int, samples: int, k_next: int, row0: int, prow0: int) -> None:
        """One launch of ``samples`` sample intervals after ``done`` of them; its first sample is the run's sample
        ``k_next``, recorded into globals row ``row0`` and per-patch row ``prow0`` of the recorder's buffers."""
        s, rec, T = self.state, self.recorder, self.model.dtype
        self.launch_kernel(
            [
                self.kernel_model,
                rec.struct,
                self.growth_every,
                done * self.sps % self.growth_every,  # steps so far (growth events count from the run's start)
                self.threads,
                T(self.h),
                self.solver.newton_tol,
                self.sps,
                samples,
                int(not self.started),
                k_next,
                prow0,
                s.u,
                s.v,
                s.force,
                self.parts,
            ],
        )
        m, (sample_rows, sample_faults) = self.model, self.extra_kernels
        parts = [self.parts, self.blocks_per_pad, self.warps, row0, self.verdicts]
        wp.launch(
            sample_rows, dim=(samples, m.pad_count), inputs=[self.kernel_model, rec.struct, *parts], device=m.device
        )
        faults = [self.kernel_model, rec.struct, self.verdicts, samples, k_next]
        wp.launch(sample_faults, dim=m.pad_count, inputs=faults, device=m.device)
