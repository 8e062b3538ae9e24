"""The interface between the run loop and an engine: :class:`Engine`, :class:`Progress`, :class:`EngineTuning`.

An engine advances the pads of one model and records samples into its recorder; the run loop
(:func:`aca_warp.hf.loop.run_hf`) does everything around it. Engines: :class:`aca_warp.hf.general.GeneralEngine`
(per-step kernels, every integrator) and :class:`aca_warp.hf.onchip.OnchipEngine` (one block or cluster per pad).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import warp as wp

from aca_warp.common.errors import SimulationFault
from aca_warp.hf.model import PadModel
from aca_warp.hf.options import RunOptions
from aca_warp.hf.recorder import Recorder
from aca_warp.hf.solver import StepEstimate
from aca_warp.hf.state import HFState
from aca_warp.scene import Record


@dataclass
class Progress:
    """Where an engine stands after a chunk.

    Attributes:
        samples: Sample intervals completed (fixed-step engines; 0 for the adaptive one, whose clock is on the device).
        steps: Accepted steps.
        rejected: Rejected steps (adaptive only).
        sim_time: Simulated time reached [s].
        done: True when the whole duration is simulated.
        fault: A fault the engine itself detected (e.g. step-size underflow), or None.
    """

    samples: int = 0
    steps: int = 0
    rejected: int = 0
    sim_time: float = 0.0
    done: bool = False
    fault: SimulationFault | None = None


class Engine(Protocol):
    """What the run loop needs of an engine (constructed for one model, state, options and record)."""

    recorder: Recorder
    estimate: StepEstimate
    stages: list[str]
    blocks_per_pad: int
    block_dim: int | None  # threads per block of the on-chip launches (None: per-patch kernels)
    capture_time: float  # wall time spent capturing graphs inside advance() [s]
    cause: str  # the likely cause of a fault, in words

    def saved(self) -> dict[str, wp.array]:
        """Device arrays a checkpoint holds besides the state, the recorder counters and the watchdog bound."""
        ...

    def begin(self, resume: dict[str, int] | None) -> None:
        """Record sample 0, or take a checkpoint's counters (its arrays are restored already)."""
        ...

    def advance(self, progress: Progress, most: int) -> Progress:
        """Advance one chunk from ``progress``, recording into the recorder; a fixed-step engine stops after at most
        ``most`` sample intervals (so that a chunk ends at the next checkpoint)."""
        ...

    def counters(self) -> dict[str, int]:
        """The engine's counters a checkpoint stores."""
        ...

    def step_used(self) -> float:
        """The fixed step used, or the adaptive controller's last desired step [s]."""
        ...

    def finish(self) -> None:
        """Leave the state synchronous (strang's staggered velocity closed)."""
        ...


def run_stages(model: PadModel, recorder: Recorder, step: str) -> list[str]:
    """The stages a run file names for an engine stepping ``step`` (e.g. ``strang``, ``adaptive:onchip``)."""
    stages = ["contact", "neighbours" if model.has_coupling else "no-coupling", f"step:{step}", "record:globals"]
    stages += ["record:patches"] if recorder.patch_stage else []
    return stages + (["growth"] if "pad_growth" in model.arrays else [])


def fault_cause(estimate: StepEstimate, integrator: str, h: float | None) -> str:
    """The likely cause of a fault of a run of fixed step ``h`` [s] (None: adaptive), in words."""
    limit = estimate.limit(integrator)
    if h is not None and h > limit:
        return f"step {h:.3g} s beyond the stable estimate {limit:.3g} s"
    return "extreme scene parameters (check loads, areas, speeds)"


@dataclass(frozen=True)
class EngineTuning:
    """Engine settings that do not change results (general) or only by rounding (on-chip); for benchmarks.

    Attributes:
        use_graph: General engine: replay captured graphs (False: launch eagerly, for debugging).
        max_graph_steps: General engine: most steps per captured graph.
        block_dim: On-chip: threads per block (None: :func:`~aca_warp.hf.onchip_layout.default_block`).
        csr_shared: On-chip: neighbour lists in shared memory (None: when they fit).
        samples_per_launch: On-chip: sample intervals per launch (None: strang ~20k steps, adaptive 256; fewer on the
            CPU for large batches).
        cluster: On-chip: blocks per pad (None: :func:`~aca_warp.hf.onchip_layout.default_cluster` on sm_90+).
        ablate: On-chip profiling only: parts of the step left out (results wrong).
    """

    use_graph: bool = True
    max_graph_steps: int = 256
    block_dim: int | None = None
    csr_shared: bool | None = None
    samples_per_launch: int | None = None
    cluster: int | None = None
    ablate: frozenset[str] = frozenset()


@dataclass(frozen=True)
class EngineSetup:
    """What an engine is built for (:func:`aca_warp.hf.loop.make_engine`).

    Attributes:
        model: The pads' model.
        state: The state the engine advances (in place).
        options: The run's options.
        record: What and how often to record.
        n_samples: Sample intervals of the run.
        tuning: Engine settings that do not change results.
        estimate: The model's stable-step estimate when the run has it already (it reads every link of the batch),
            else None (the engine's solver computes it).
    """

    model: PadModel
    state: HFState
    options: RunOptions
    record: Record
    n_samples: int
    tuning: EngineTuning
    estimate: StepEstimate | None = None
