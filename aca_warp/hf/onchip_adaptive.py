"""On-chip engine of the ``adaptive`` integrator: a thread block or cluster per pad runs its own DP5(4) trials and
samples.

Where the general engine runs a trial of every pad as 14 launches and lands every pad on each sample before any
goes on (:mod:`aca_warp.hf.adaptive`), this engine runs one launch per chunk of sample intervals: each block
steps its pad with its own clock, error control and samples (:mod:`aca_warp.kernels.hf_onchip_adaptive`), so a
one-pad run pays a barrier per stage instead of a kernel launch, its gathers read shared memory, and a batch never
waits for its slowest pad between samples; a growing pad lands on its growth events and grows itself there. A pad
whose stage displacements do not fit shared memory runs on the general engine
(:func:`~aca_warp.hf.onchip_layout.unsupported`). Initial control, error scales, event times and checkpointed
arrays are the general engine's (:class:`~aca_warp.hf.adaptive.AdaptiveStepper`,
:class:`~aca_warp.hf.general.Growth`); on the CPU the runs are bit-identical to it.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from aca_warp.common.devices import block_threads
from aca_warp.common.errors import SceneError
from aca_warp.hf import adaptive
from aca_warp.hf.engine import EngineSetup, EngineTuning, Progress, fault_cause, run_stages
from aca_warp.hf.general import Growth
from aca_warp.hf.model import PadModel
from aca_warp.hf.onchip import OnchipLaunches, cluster_size
from aca_warp.hf.onchip_layout import adaptive_shared_bytes, pad_sizes, smem_limit, unsupported
from aca_warp.hf.recorder import Recorder
from aca_warp.hf.solver import HFSolver, grown_arrays
from aca_warp.kernels import hf_adaptive as KA
from aca_warp.kernels import hf_onchip_adaptive as KO

BLOCK = 512  # most threads per block by default
# Threads per patch of a stage evaluation on CUDA when a block's patches take at most BLOCK threads that way (else
# 1, and always 1 on the CPU): chosen from runs of one hf1 pad (1 ms, tol 1e-5, fp64) on an H200 with 1, 4, 8, 16
# and 32 lanes on 8 and 16 blocks (4 lanes on 16 blocks the fastest, 20 % ahead of one lane), and of 64 pads on 2
# blocks, where lanes made it 2× slower (scripts/profile_onchip_adaptive.py --cluster K --lanes L; docs/onchip.md).
EVAL_LANES = 4
WIDE_CLUSTER = 16  # blocks per pad for at most one pad per GPC (18 SMs) where the device launches them (else 8)
SAMPLES_PER_LAUNCH = 256  # sample intervals per launch (a chunk; the recorder holds one launch's rows)
# on the CPU (a pad's block is one thread) also at most about this many patch-samples per launch, so that progress,
# Ctrl-C and checkpoints stay timely on large batches: a sample of a sliding hf1 pad takes a few trials, of the
# stick-slip one of docs/time_to_solution.md ~29 at tolerance 1e-5, ~0.27 µs per patch-trial there: ~1.6 s a launch
CPU_PATCH_SAMPLES_PER_LAUNCH = 200_000


def tile_sizes(model: PadModel, cluster: int) -> tuple[int, int]:
    """(patches of the shared stage displacements, links of a block's shared neighbour lists or 0): the largest pad
    rounded up to 32, and the most links of one block of ``cluster`` when they fit shared memory beside the
    displacements (else 0: the lists are read from global memory)."""
    nmax = -(-pad_sizes(model)[0] // 32) * 32
    links = -(-pad_sizes(model, cluster)[1] // 32) * 32
    fits = adaptive_shared_bytes(model, cluster, links) <= smem_limit(model)
    return nmax, links if fits else 0


def layout(model: PadModel, tuning: EngineTuning) -> tuple[int, int, int, wp.Kernel]:
    """(blocks per pad, lanes per patch, threads per block, kernel) from ``tuning`` or the defaults: the strang
    engine's cluster rule, but WIDE_CLUSTER blocks for up to one pad per 18 SMs where the device can launch them;
    EVAL_LANES lanes where a block's patches fit BLOCK threads so; the threads a block's patches need that way,
    rounded up to 32, at most BLOCK."""
    dev = model.device
    most = int(np.diff(model.pad_patch_start_host).max())
    cluster = cluster_size(model, tuning.cluster, split_fits_csr=False)
    wide = tuning.cluster is None and cluster == 8 and model.pad_count <= max(dev.sm_count // 18, 1)
    for k in (WIDE_CLUSTER, cluster) if wide else (cluster,):
        per_block = -(-most // k)
        lanes = EVAL_LANES if dev.is_cuda and per_block * EVAL_LANES <= BLOCK else 1
        block_dim = tuning.block_dim or min(BLOCK, -(-per_block * lanes // 32) * 32)
        if not 1 <= block_dim <= 1024 or block_dim % lanes:
            raise SceneError(f"block_dim must be in [1, 1024] and a multiple of {lanes}, got {block_dim}")
        kernel = KO.onchip_dp5_kernel(
            model.dtype,
            k,
            block_dim,
            lanes,
            *tile_sizes(model, k),
            frozenset(tuning.ablate),
            "pad_growth" in model.arrays,
        )
        if k == 1 or wp.get_cuda_max_cluster_dim(kernel, dev, block_dim=block_dim) >= k:
            return k, lanes, block_dim, kernel
        if k == cluster:
            raise SceneError(f"{dev.name} cannot launch a cluster of {k} blocks of {block_dim} threads per pad")
    raise AssertionError("unreachable")


class OnchipAdaptiveEngine(OnchipLaunches):
    """The on-chip ``adaptive`` kernel (:class:`~aca_warp.hf.engine.Engine`). Tuning: ``cluster`` blocks per pad
    (default :func:`layout`: 16 for one hf1 pad on an H100/H200, else as the strang engine), ``block_dim`` threads
    per block (default :func:`layout`), ``samples_per_launch`` sample intervals per launch (default
    ``SAMPLES_PER_LAUNCH``; on the CPU at most ``CPU_PATCH_SAMPLES_PER_LAUNCH`` patch-samples, at least one),
    ``ablate`` (profiling only: ``kernels.hf_onchip_adaptive.ABLATIONS``). On the CPU a block is one thread unless
    Warp's CPU fibers are on."""

    def __init__(self, setup: EngineSetup) -> None:
        model, state, options, record = setup.model, setup.state, setup.options, setup.record
        n_samples, tuning = setup.n_samples, setup.tuning
        why = unsupported(model, "adaptive")
        if why is not None:
            raise SceneError(f"on-chip engine: {why}")
        self.model, self.state, self.record, self.n_samples = model, state, record, n_samples
        self.solver = HFSolver.for_run(model, options, setup.estimate)
        self.estimate = self.solver.estimate
        spl = SAMPLES_PER_LAUNCH if tuning.samples_per_launch is None else tuning.samples_per_launch
        if tuning.samples_per_launch is None and model.device.is_cpu:
            spl = min(spl, max(1, CPU_PATCH_SAMPLES_PER_LAUNCH // model.patch_count))
        if spl < 1:
            raise SceneError(f"samples_per_launch must be at least 1, got {spl}")
        self.spl = min(spl, n_samples)
        self.blocks_per_pad, self.lanes, self.block_dim, self.kernel = layout(model, tuning)
        self.threads = block_threads(model.device, self.block_dim)
        self.recorder = Recorder(model, record, self.spl + 1, n_samples)
        self.t_end = n_samples * record.sample_dt
        # the event times and the increment per event (its flag and launches are the general engine's, unused here)
        self.growth = Growth(model, None, self.solver.growth_dt) if "pad_growth" in model.arrays else None
        self.stepper = adaptive.AdaptiveStepper(model, state, self.solver, self.recorder, self.t_end, self.growth)
        self.kernel_model = model.struct(None if self.growth is None else self.growth.per_event)
        self.stages = run_stages(model, self.recorder, "adaptive:onchip")
        self.cause = fault_cause(self.estimate, "adaptive", None)

    # -- the Engine protocol

    def saved(self) -> dict[str, wp.array]:
        return self.stepper.saved() | grown_arrays(self.model)

    def advance(self, p: Progress, most: int) -> Progress:
        rec = self.recorder
        reps, k_next, rows, prows = self.launch_rows(p, most)
        self._launch(reps, k_next, rows, prows)
        self.started = True
        mode = self.stepper.mode.numpy()
        # samples recorded by every pad: up to its target's, less the one it is heading for
        reached = int((mode[:, KA.M_SAMPLE] - 1 + mode[:, KA.M_LANDED]).min())
        done_here = max(0, min(reps, reached - (k_next - 1)))
        rec.kernel_recorded(k_next, rows, prows, done_here)
        st = self.stepper.stats.numpy()
        samples = p.samples + done_here
        t = samples * self.record.sample_dt
        fault = None
        if self.stepper.done.numpy()[2]:
            fault = adaptive.underflow_fault(t)
        return Progress(samples, int(st[:, 0].max()), int(st[:, 1].sum()), t, samples >= self.n_samples, fault)

    def step_used(self) -> float:
        return self.stepper.mean_step()

    def finish(self) -> None:
        """Nothing to close: the adaptive state is synchronous."""

    def _launch(self, samples: int, k_next: int, rows: int, prows: int) -> None:
        """One launch of ``samples`` sample intervals, rows counted from the recorder's."""
        s, rec, st = self.state, self.recorder, self.stepper
        self.launch_kernel(
            [self.kernel_model, rec.struct, st.struct, self.threads, samples, k_next, rows, prows, s.u, s.v]
        )
