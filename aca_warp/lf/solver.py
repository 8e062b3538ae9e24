"""Device state of the LF automaton and the step sequence (one launch per rule; kernels in ``aca_warp.kernels.lf_*``).

One LF step (docs/lf_model.md, "One step, in order"): load from the schedule → bin patches into cells → contact solve
(Newton on the gap) → friction, powers → temperatures (implicit) → wear → debris sweep → capture → growth,
shrink, death → merge → birth → statistics and history row. In pauses only the temperatures run (cooling)
and μ is recorded as 0. The only host read per step is the topology flag, which triggers the rebuild of the
merge-candidate neighbourhoods (CSR from ``wp.HashGrid``) when patches were born or merged. On CUDA the rest of the
step (``_body``) is captured once per step kind (loaded / pause) into a graph and replayed (CUDA and CPU).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import warp as wp

from aca_warp.common.checkpoint import Checkpoint, CheckpointClock
from aca_warp.common.devices import block_threads, get_device, load_kernels
from aca_warp.common.errors import SceneError
from aca_warp.common.progress import LogProgress
from aca_warp.hf.options import check_interval
from aca_warp.kernels import lf_contact, lf_patches, lf_record, lf_sums, lf_thermal, lf_wear
from aca_warp.kernels.lf_record import H_COUNT, H_COVER, H_MU, H_NAMES, H_SIZE
from aca_warp.kernels.lf_types import (
    G_EMITTED,
    G_GAP,
    G_LOAD,
    G_MATRIX_IN,
    G_OMEGA,
    G_PATCH_LOST,
    G_SIZE,
    G_TOPOLOGY,
    LF_BLOCK,
    LFCells,
    LFParams,
    LFPatches,
    LFRings,
)
from aca_warp.lf.scene import LFScene, StepTable, step_table
from aca_warp.scene import Patches, overlapping_pairs

TERMINAL_INTERVAL = 2.0  # s of wall time between two progress lines on a terminal (a log: common.progress)

# Empty slots are parked in the hash grid at one point half the grid's y period (64 of 128 cell rows) away from
# the pad's middle row: the grid wraps cell coordinates modulo 128, so parking them "far away" can land them in a
# row the pad's queries visit (1000 m did, at the multiscale cell size: every query near that row then walked
# ~170 empty slots, ~100 µs per candidate kernel on an H100). Half a period away, no query of a pad less than
# ~120 cells tall visits them.
_PARK_ROWS = 64
# the arrays of LFPatches fields named otherwise here (the rest: the field's name)
_PATCH_ARRAYS = {"fn": "patch_fn", "power": "patch_power", "cell": "patch_cell"}
_BIRTH_ARRAYS = {"xy": "birth_xy", "slot": "slot_list"}
# arrays a checkpoint leaves out: constants of the grid and schedule, the history (the run file's /global) and
# per-step scratch (written in a step before it is read)
_CONSTANT_ARRAYS = (
    "cell_area", "cell_r", "ring_r", "schedule", "hist", "kh", "partial", "patch_src", "died", "died_at",
    "group_count", "group_fill", "group_start", "group_cell", "group_ring",
)  # fmt: skip


class LFSimulation:
    """The LF model and state of one pad on one device (float64 throughout).

    Grid: R = n_r rings × n_t columns = C cells (ring-major). Per cell (C,): ``cell_area`` A_e [m²], ``cell_r``
    [m], ``cell_x``/``cell_y`` [m] (host), ``cell_z`` elevation [m], ``cell_T`` [K], ``cell_store`` [kg],
    ``cell_src`` pending debris [kg], ``cell_fn`` [N], ``cell_power`` [W], ``cell_cover`` [m²], ``cell_chord`` [m].
    Per ring (R,): ``ring_r`` [m], ``ring_T`` [K], ``ring_bulge`` [m], ``ring_power`` [W].
    Per patch slot (P,): ``alive``, ``x``, ``y`` [m], ``area`` [m²], ``thick`` t [m], ``top`` free elevation of the
    patch top [m], ``temp`` [K], ``mcap`` [kg], ``age`` [s], ``patch_fn`` [N], ``patch_power`` [W], ``patch_cell``.
    ``glob`` holds the global scalars (``aca_warp.kernels.lf_types.G_*``), ``hist`` (steps, H_SIZE) the outputs.
    The kernels take the cells, rings and patch slots as the structs ``cells``, ``rings`` and ``patches``
    (:class:`~aca_warp.kernels.lf_types.LFCells` …) of these arrays.
    """

    def __init__(
        self, scene: LFScene, *, device: str = "cpu", duration: float | None = None, graph: bool | None = None
    ) -> None:
        self.device = get_device(device)
        load_kernels([lf_contact, lf_patches, lf_record, lf_sums, lf_thermal, lf_wear], self.device)
        self.scene = scene
        self.table: StepTable = step_table(scene, duration)
        dr, dphi = self._set_grid()
        self.params = self._lf_params(dr, dphi)
        ring_r = self._set_cell_geometry(dr, dphi)
        self._allocate(ring_r)
        self.step_index = 0
        self.rebuilds = 0  # merge-candidate rebuilds so far (reported by scripts/bench_lf.py)
        self.wall_time = 0.0  # [s] of the last run call, and its rate over the steps it ran [1/s]: set by the
        self.steps_per_second = 0.0  # command that runs it (aca_warp.lf.commands)
        self.dirty = True
        if scene.patches is not None:
            self._place(scene.patches)
        # graphs of the step body (one for loaded steps, one for pauses), on by default: CUDA graphs, and on the
        # CPU Warp 1.19's recorded launches and scans (bit-identical to eager, ~3x fewer µs per launch)
        self.use_graph = True if graph is None else bool(graph)
        self._graphs: dict[bool, Any] = {}
        self._seen: set[bool] = set()

    def _set_grid(self) -> tuple[float, float]:
        """Ring and column counts of the cell grid (cells of about ``lf.cell`` [m]), the launch sizes and the slot
        capacity; returns the ring width dr [m] and the column angle dφ [rad]."""
        c, pad = self.scene.lf, self.scene.pad
        n_r = max(int(round((pad.r_outer - pad.r_inner) / c.cell)), 1)
        n_t = max(int(round(2.0 * pad.half_span * pad.mean_radius / c.cell)), 1)
        self.n_r, self.n_t = n_r, n_t
        self.n_cells = n_r * n_t
        self.threads = block_threads(self.device, LF_BLOCK)  # threads a block kernel's block runs
        self.element_blocks = -(-(self.n_cells + c.capacity) // LF_BLOCK)  # blocks covering the C + P elements
        self.capacity = c.capacity
        return (pad.r_outer - pad.r_inner) / n_r, 2.0 * pad.half_span / n_t

    def _lf_params(self, dr: float, dphi: float) -> Any:
        """The kernels' ``LFParams``: the grid, the scene's material and friction, and every ``lf`` constant the
        struct has a field for."""
        scene, c, pad = self.scene, self.scene.lf, self.scene.pad
        p = LFParams()
        vals = dict(
            r_in=pad.r_inner, dr=dr, half=pad.half_span, dphi=dphi, n_r=self.n_r, n_t=self.n_t, dt=c.dt,
            seed=c.seed, K_N=scene.material.K_N, k_m=scene.material.matrix_stiffness, mu_pad=scene.friction.mu_pad,
            coulomb=c.coulomb, mu_coulomb=c.mu_coulomb, M=scene.friction.M, slope=scene.friction.slope,
            decay=scene.friction.decay,
        )  # fmt: skip
        for f in dataclasses.fields(c):
            if hasattr(p, f.name) and f.name not in vals:
                vals[f.name] = getattr(c, f.name)
        for k, v in vals.items():
            setattr(p, k, v)
        return p

    def _set_cell_geometry(self, dr: float, dphi: float) -> np.ndarray:
        """Host arrays of the cells (C,): centre radius, x, y [m], exact annular-sector area [m²] and area-weighted
        radius [m]; returns the ring radii [m], shape (R,)."""
        pad, n_r, n_t = self.scene.pad, self.n_r, self.n_t
        ring_r = pad.r_inner + (np.arange(n_r) + 0.5) * dr
        phi = -pad.half_span + (np.arange(n_t) + 0.5) * dphi
        rr, pp = np.meshgrid(ring_r, phi, indexing="ij")
        self.cell_r_host = rr.ravel()
        self.cell_x_host = (-rr * np.sin(pp)).ravel()
        self.cell_y_host = (rr * np.cos(pp)).ravel()
        # exact annular-sector cell areas: Σ A_e = pad area
        edges = pad.r_inner + np.arange(n_r + 1) * dr
        ring_area = 0.5 * dphi * (edges[1:] ** 2 - edges[:-1] ** 2)
        self.cell_area_host = np.repeat(ring_area, n_t)
        self.cell_rc_host = np.repeat(
            2.0 / 3.0 * (edges[1:] ** 3 - edges[:-1] ** 3) / (edges[1:] ** 2 - edges[:-1] ** 2), n_t
        )
        return ring_r

    def _allocate(self, ring_r: np.ndarray) -> None:
        """Every device array of the state (class docstring), the hash grid with its radii and parking point, the
        load schedule, the global scalars and the history."""
        dev = self.device
        C, R, P = self.n_cells, self.n_r, self.capacity
        c, pad = self.scene.lf, self.scene.pad
        f64 = lambda a: wp.array(np.asarray(a, dtype=np.float64), dtype=wp.float64, device=dev)  # noqa: E731
        zf = lambda n: wp.zeros(n, dtype=wp.float64, device=dev)  # noqa: E731
        zi = lambda n: wp.zeros(n, dtype=wp.int32, device=dev)  # noqa: E731
        self.cell_area = f64(self.cell_area_host)
        self.cell_r = f64(self.cell_rc_host)
        self.ring_r = f64(ring_r)
        self.cell_z, self.cell_store, self.cell_src = zf(C), zf(C), zf(C)
        self.cell_T = f64(np.full(C, c.T_amb))
        self.cell_fn, self.cell_power, self.cell_cover, self.cell_chord, self.cell_capture = (zf(C) for _ in range(5))
        self.ring_T = f64(np.full(R, c.T_amb))
        self.ring_bulge, self.ring_power, self.ring_emit = zf(R), zf(R), zf(R)
        self.work = zf(2 * R)
        self.kh = wp.zeros(C + P, dtype=wp.vec2d, device=dev)  # contact scratch: (k [N/m], h [m]) per element
        # order-fixed sums (kernels/lf_sums.py): the block kernels' per-block sums, a patch's debris for its cell
        # [kg], a death's flag and (age [s], area [m²]) per slot, the patches grouped by cell and ring
        self.partial = wp.zeros((self.element_blocks, 4), dtype=wp.float64, device=dev)
        self.patch_src = zf(P)
        self.died = zi(P)
        self.died_at = wp.zeros(P, dtype=wp.vec2d, device=dev)
        self.group_count, self.group_fill, self.group_start = zi(C), zi(C), zi(C + 1)
        self.group_cell, self.group_ring = zi(P), zi(P)
        self.alive, self.patch_cell, self.target = zi(P), zi(P), zi(P)
        self.x, self.y, self.area, self.thick, self.top = (zf(P) for _ in range(5))
        self.temp = f64(np.full(P, c.T_amb))
        self.mcap, self.age, self.patch_fn, self.patch_power = (zf(P) for _ in range(4))
        self.free, self.free_rank, self.slot_list = zi(P), zi(P), zi(P)
        self.want, self.want_rank = zi(C), zi(C)
        self.birth_xy = wp.zeros(C, dtype=wp.vec2d, device=dev)
        self.death_count = zi(1)
        self.death_age, self.death_area = zf(200_000), zf(200_000)
        self.pos = wp.zeros(P, dtype=wp.vec3d, device=dev)
        self.cand_count = zi(P)
        self.cand_start = zi(P + 1)
        self.cand_index = zi(max(16 * P, 1))
        self.grid = wp.HashGrid(128, 128, 1, device=dev, dtype=wp.float64)
        a_big = math.sqrt(2.0 * c.A_max / math.pi)
        self.cand_radius = 2.0 * a_big + c.cand_margin
        self.birth_radius = math.sqrt(c.A0 / math.pi) + a_big + c.cand_margin
        y_mid = 0.5 * (pad.r_inner * math.cos(pad.half_span) + pad.r_outer)
        self.park = (0.0, y_mid + _PARK_ROWS * self.cand_radius, 0.0)  # hash-grid point of the empty slots [m]
        sched = np.column_stack([self.table.load, self.table.omega]).astype(np.float64)
        self.schedule = wp.array(sched, dtype=wp.float64, device=dev)
        self.glob = zf(G_SIZE)
        self.hist = wp.zeros((self.table.steps, H_SIZE), dtype=wp.float64, device=dev)
        # the kernels' parameter groups of the state, built once: the arrays change in place (captured graphs keep them)
        self.cells, self.rings, self.patches = LFCells(), LFRings(), LFPatches()
        for f in LFCells.vars:
            setattr(self.cells, f, getattr(self, f"cell_{f}"))
        for f in LFRings.vars:
            setattr(self.rings, f, getattr(self, f"ring_{f}"))
        for f in LFPatches.vars:
            setattr(self.patches, f, getattr(self, _PATCH_ARRAYS.get(f, f)))
        self.births = lf_patches.LFBirths()
        for f in lf_patches.LFBirths.vars:
            setattr(self.births, f, getattr(self, _BIRTH_ARRAYS.get(f, f)))
        self.groups = lf_sums.LFGroups()
        for f in lf_sums.LFGroups.vars:
            setattr(self.groups, f, getattr(self, f"group_{f}"))

    # ------------------------------------------------------------------------------------------- set-up

    def _place(self, patches: Patches) -> None:
        n = patches.count
        if n > self.capacity:
            raise SceneError(f"{n} initial patches exceed lf.capacity = {self.capacity}")
        for name, val in (("x", patches.x), ("y", patches.y), ("area", patches.area)):
            a = getattr(self, name).numpy()
            a[:n] = val
            getattr(self, name).assign(a)
        alive = np.zeros(self.capacity, dtype=np.int32)
        alive[:n] = 1
        self.alive.assign(alive)
        th = np.zeros(self.capacity)
        th[:n] = patches.height
        self.thick.assign(th)
        self.top.assign(th)  # matrix starts flat at z = 0

    # ------------------------------------------------------------------------------------------- step

    def _launch(self, kernel: Any, dim: int, inputs: list) -> None:
        wp.launch(kernel, dim=dim, inputs=inputs, device=self.device)

    def _launch_blocks(self, kernel: Any, blocks: int, inputs: list) -> None:
        """A block kernel: ``blocks`` thread blocks of LF_BLOCK threads (``wp.launch_tiled``)."""
        wp.launch_tiled(kernel, dim=[blocks], block_dim=LF_BLOCK, inputs=inputs, device=self.device)

    def rebuild_neighbours(self) -> None:
        """Merge-candidate CSR (alive pairs within ``cand_radius``) and the birth hash grid, from current positions."""
        P = self.capacity
        self._launch(lf_patches.positions3, P, [self.patches, wp.vec3d(*self.park), self.pos])
        self.grid.build(self.pos, self.cand_radius)
        cand = [self.grid.id, wp.float64(self.cand_radius), self.alive, self.pos, self.cand_start]
        self._launch(lf_patches.candidates, P, [*cand, 0, self.cand_count, self.cand_index])
        wp.utils.array_scan(self.cand_count, self.cand_start[:P], inclusive=False)
        self._launch(lf_patches.set_row_end, 1, [self.cand_count, self.cand_start, P])
        total = int(self.cand_start.numpy()[P])
        if total > self.cand_index.shape[0]:
            self.cand_index = wp.zeros(int(total * 1.5) + 16, dtype=wp.int32, device=self.device)
            self._graphs.clear()  # the graphs hold the old buffer
        self._launch(lf_patches.candidates, P, [*cand, 1, self.cand_count, self.cand_index])
        self.dirty = False
        self.rebuilds += 1

    def _bin(self) -> None:
        """Reset the step's accumulators, bin the patches into the cells, group them and sum the cells' cover."""
        self._launch(lf_contact.zero_step, self.n_cells, [self.cells, self.rings, self.glob])
        self._launch(lf_contact.bin_patches, self.capacity, [self.params, self.patches])
        self._group()
        self._launch(lf_contact.cover_chord, self.n_cells, [self.groups, self.patches, self.cells])

    def _group(self) -> None:
        """Group the alive patches by their cell (``patch_cell``) and ring, ascending slots in each group: a cell's
        few patches are filled in any order and sorted, a ring's placed at their ranks."""
        C, P, groups = self.n_cells, self.capacity, self.groups
        self.group_count.zero_()
        self.group_fill.zero_()
        self._launch(lf_sums.group_count, P, [self.alive, self.patch_cell, groups])
        wp.utils.array_scan(self.group_count, self.group_start[:C], inclusive=False)
        self._launch(lf_patches.set_row_end, 1, [self.group_count, self.group_start, C])
        self._launch(lf_sums.group_fill, P, [self.alive, self.patch_cell, groups])
        self._launch(lf_sums.group_sort, C, [groups])
        self._launch(lf_sums.ring_order, P, [self.patch_cell, self.n_t, groups])

    def _add_patch_src(self) -> None:
        """Add the patches' debris (``patch_src``) to their cells' sources, in slot order."""
        self._launch(lf_sums.add_by_cell, self.n_cells, [self.groups, self.patch_src, self.cell_src])

    def _contact_and_friction(self) -> None:
        p, C, P = self.params, self.n_cells, self.capacity
        cells, rings, patches = self.cells, self.rings, self.patches
        self._launch(lf_contact.contact_elements, C + P, [p, C, cells, rings, patches, self.kh])
        lf = self.scene.lf
        tol = wp.float64(lf.contact_tol)
        self._launch_blocks(lf_contact.contact_solve, 1, [lf.contact_iterations, tol, self.threads, self.kh, self.glob])
        fric = [p, C, self.threads, self.kh, cells, patches, self.glob, self.partial]
        self._launch_blocks(lf_contact.friction, self.element_blocks, fric)
        self._launch(lf_sums.add_block_sums, 4, [self.partial, lf_contact.FRICTION_SUMS, self.glob])
        self._launch_blocks(lf_contact.ring_power, self.n_r, [p, self.threads, self.groups, cells, patches, rings])

    def resolve(self) -> None:
        """Re-bin the patches and re-solve contact and friction at the current load, without advancing time."""
        self._bin()
        self._contact_and_friction()

    def step(self) -> None:
        """Advance one LF step (the step counter on the device advances with it)."""
        if self.step_index >= self.table.steps:
            raise SceneError("the schedule is over")
        loaded = bool(self.table.load[self.step_index] > 0.0)
        if self.dirty:
            self.rebuild_neighbours()
        if self.use_graph and loaded in self._seen:
            if loaded not in self._graphs:
                try:
                    with wp.ScopedCapture(device=self.device) as cap:
                        self._body(loaded)
                    self._graphs[loaded] = cap.graph
                except Exception as e:  # pragma: no cover - depends on the CUDA driver
                    print(f"aca-warp lf: graph capture failed ({e}); running eagerly", flush=True)
                    self.use_graph = False
            if self.use_graph:
                wp.capture_launch(self._graphs[loaded])
            else:
                self._body(loaded)
        else:
            self._body(loaded)
            self._seen.add(loaded)
        self.step_index += 1
        if loaded and int(self.glob.numpy()[G_TOPOLOGY]) != 0:
            self.dirty = True
        c = self.scene.lf.compact_every
        if c and self.step_index % c == 0:
            self.compact()

    def _body(self, loaded: bool) -> None:
        """The launches of one step after the neighbourhood rebuild (graph-capturable: no host reads)."""
        p, C, P, R = self.params, self.n_cells, self.capacity, self.n_r
        cells, rings, patches = self.cells, self.rings, self.patches
        self._bin()
        self._launch(lf_record.set_load, 1, [self.schedule, self.glob])
        if loaded:
            self._contact_and_friction()
        else:
            self.cell_fn.zero_()
            self.cell_power.zero_()
            self.patch_fn.zero_()
            self.patch_power.zero_()
        self._launch_blocks(lf_thermal.disc_temperature, 1, [p, self.threads, rings, self.work])
        self._launch(lf_thermal.pad_temperature, C, [p, C, 0, cells, rings, patches])
        self._launch(lf_thermal.pad_temperature, P, [p, C, C, cells, rings, patches])
        if loaded:
            wear = [p, C, self.threads, cells, patches, self.patch_src, self.partial]
            self._launch_blocks(lf_wear.wear, self.element_blocks, wear)
            self._launch(lf_sums.add_block_sums, 3, [self.partial, lf_wear.WEAR_SUMS, self.glob])
            self._add_patch_src()
            self._launch_blocks(lf_wear.debris_sweep, R, [p, self.threads, cells, rings])
            self._launch(lf_wear.capture_gather, P, [cells, patches])
            life = [p, patches, self.glob, self.patch_src, self.died, self.died_at]
            self._launch(lf_patches.life_cycle, P, life)
            self._add_patch_src()
            self.merge()
            self._birth()
        deaths = [self.glob, self.death_count, self.death_age, self.death_area]
        self._launch_blocks(lf_record.patch_stats, 1, [self.threads, patches, self.died, self.died_at, *deaths])
        self._launch(lf_record.record_step, 1, [wp.float64(self.scene.pad.area), rings, self.glob, self.hist])

    def merge(self) -> None:
        """One merge pass over the candidate CSR: each root absorbs the patches that overlap it (lowest index).
        The patches must be grouped by their cells (:meth:`_group`) since their last binning."""
        P, cand = self.capacity, (self.cand_start, self.cand_index)
        self._launch(lf_patches.merge_target, P, [*cand, self.patches, self.target])
        merge = [self.params, *cand, self.target, self.patches, self.glob, self.patch_src]
        self._launch(lf_patches.merge_apply, P, merge)
        self._add_patch_src()
        self._launch(lf_patches.merge_kill, P, [self.target, self.patches])

    def _birth(self) -> None:
        p, C, P = self.params, self.n_cells, self.capacity
        state = [self.cells, self.patches, self.glob]
        radius = wp.float64(self.birth_radius)
        self._launch(lf_patches.birth_want, C, [p, self.grid.id, radius, *state, self.births])
        self._launch(lf_patches.free_slots, P, [self.patches, self.births])
        wp.utils.array_scan(self.free, self.free_rank, inclusive=False)
        self._launch(lf_patches.free_list, P, [self.births])
        wp.utils.array_scan(self.want, self.want_rank, inclusive=False)
        self._launch(lf_patches.birth_apply, C, [p, self.births, *state])

    def compact(self) -> None:
        """Move the alive patches to the front of the slot arrays, keeping their order (prefix sum)."""
        P = self.capacity
        a = self.alive.numpy()
        if a[: int(a.sum())].all():
            return
        rank = wp.zeros(P, dtype=wp.int32, device=self.device)
        wp.utils.array_scan(self.alive, rank, inclusive=False)
        dst = wp.zeros(P, dtype=wp.int32, device=self.device)
        self._launch(lf_patches.compact_map, P, [self.alive, rank, dst])
        # in place (scatter to a scratch array, copy back), so captured graphs keep valid buffers
        tmp = wp.zeros(P, dtype=wp.float64, device=self.device)
        for name in ("x", "y", "area", "thick", "top", "temp", "mcap", "age", "patch_fn", "patch_power"):
            tmp.fill_(self.scene.lf.T_amb if name == "temp" else 0.0)
            self._launch(lf_patches.scatter, P, [dst, getattr(self, name), tmp])
            wp.copy(getattr(self, name), tmp)
        tmpi = wp.zeros(P, dtype=wp.int32, device=self.device)
        for name in ("alive", "patch_cell"):
            tmpi.zero_()
            self._launch(lf_patches.scatter, P, [dst, getattr(self, name), tmpi])
            wp.copy(getattr(self, name), tmpi)
        self.dirty = True

    # ------------------------------------------------------------------------------------------- runs

    def run(
        self,
        steps: int | None = None,
        *,
        on_snapshot: Callable[[str, LFSimulation], None] | None = None,
        progress: bool = False,
        checkpoint_every: float | None = None,
        on_checkpoint: Callable[[LFSimulation], None] | None = None,
    ) -> float:
        """Run ``steps`` steps (default: to the end of the schedule), calling ``on_snapshot`` at snapshot steps.

        With ``on_checkpoint``, the step ends that ``checkpoint_every`` names (:class:`CheckpointClock`: None
        automatic, else every that many seconds of simulated time, 0 none; after that step's snapshots; not at the
        end of the schedule) call ``on_checkpoint(self)`` (:meth:`checkpoint_state` gives what to keep). Returns
        the wall time of the stepping [s] (the first step, which loads the kernels, is included).
        """
        end = self.table.steps if steps is None else min(self.step_index + steps, self.table.steps)
        snaps = dict((s, n) for n, s in self.table.snapshots)
        dt = self.scene.lf.dt
        check_interval(checkpoint_every)
        clock = CheckpointClock(checkpoint_every if on_checkpoint is not None else 0.0, self.step_index * dt)
        t0 = time.perf_counter()
        last = t0
        tty = sys.stderr.isatty()  # progress on stderr: a line every 2 s on a terminal, every 30 s in a log
        log = LogProgress("lf:", self.table.steps * dt) if progress and not tty else None
        while self.step_index < end:
            self.step()
            s = self.step_index - 1
            if on_snapshot is not None and s in snaps:
                for name, si in self.table.snapshots:
                    if si == s:
                        on_snapshot(name, self)
            if self.step_index < self.table.steps and clock.due(self.step_index * dt):
                clock.write(lambda: on_checkpoint(self), self.step_index * dt)  # type: ignore[misc]
            if progress and tty and time.perf_counter() - last > TERMINAL_INTERVAL:
                last = time.perf_counter()
                print(f"  t = {(s + 1) * self.scene.lf.dt:7.2f} s  {self._state_text(s)}", file=sys.stderr, flush=True)
            elif log is not None:
                log.update((s + 1) * dt, lambda s=s: self._state_text(s))
        wp.synchronize_device(self.device)
        return time.perf_counter() - t0

    def _state_text(self, s: int) -> str:
        """The automaton's state after step ``s`` for a progress line: μ, the patch count and the coverage."""
        h = self.hist.numpy()[s]
        return f"mu {h[H_MU]:.3f}  patches {int(h[H_COUNT])}  coverage {h[H_COVER]:.3f}"

    # ------------------------------------------------------------------------------------------- checkpoints

    def snapshots_done(self) -> list[str]:
        """Names of the snapshots the run loop has passed (taken after steps before ``step_index``), in order."""
        return [n for n, s in self.table.snapshots if s < self.step_index]

    def checkpoint_state(self) -> Checkpoint:
        """The full state after the current step, to continue bit for bit (:meth:`restore`).

        ``arrays``: a host copy of every Warp array of the simulation (cells, rings, patch slots with ``alive``,
        temperatures, debris, wear, ``glob`` with the RNG step counter G_STEP and this step's birth/death/merge
        counts, the merge-candidate CSR and the hash-grid points ``pos``, scratch arrays), except the constants
        (``cell_area``, ``cell_r``, ``ring_r``, ``schedule``), ``hist``, whose rows are the run file's /global
        datasets, and the scratch that a step writes before it reads it (``_CONSTANT_ARRAYS``);
        ``death_age``/``death_area`` up to ``death_count``. ``counters``: ``step_index``, ``dirty`` (neighbourhoods
        stale), ``snapshots`` (snapshots taken).
        """
        arrays: dict[str, np.ndarray] = {}
        for name, value in vars(self).items():
            if isinstance(value, wp.array) and name not in _CONSTANT_ARRAYS:
                arrays[name] = value.numpy().copy()
        n = min(int(arrays["death_count"][0]), self.death_age.shape[0])
        arrays["death_age"] = arrays["death_age"][:n]
        arrays["death_area"] = arrays["death_area"][:n]
        counters = {
            "step_index": self.step_index,
            "dirty": int(self.dirty),
            "snapshots": len(self.snapshots_done()),
        }
        return Checkpoint(sim_time=self.step_index * self.scene.lf.dt, arrays=arrays, counters=counters)

    def restore(self, ckpt: Checkpoint, hist_rows: np.ndarray | None = None) -> None:
        """Continue from :meth:`checkpoint_state` of a run of the same scene and duration (``hist_rows``
        (step_index, H_SIZE): the history rows so far, from the run file). SceneError when it does not fit."""
        mine = {n for n, v in vars(self).items() if isinstance(v, wp.array) and n not in _CONSTANT_ARRAYS}
        if set(ckpt.arrays) != mine:
            diff = sorted(set(ckpt.arrays) ^ mine)
            raise SceneError(f"the checkpoint does not fit this LF run (arrays differ: {', '.join(diff)})")
        step = int(ckpt.counters["step_index"])
        if not 0 < step <= self.table.steps:
            raise SceneError(f"the checkpoint's step {step} is outside this run's {self.table.steps} steps")
        for name, data in ckpt.arrays.items():
            cur = getattr(self, name)
            data = np.asarray(data)
            if name in ("death_age", "death_area"):
                full = np.zeros(cur.shape, dtype=np.float64)
                full[: len(data)] = data
                data = full
            want = cur.numpy().shape  # (n,) or (n, 2|3) for vector types
            if name == "cand_index" and data.ndim == 1 and data.dtype == np.int32:
                if data.shape != cur.shape:  # grown during the run
                    setattr(self, name, wp.array(data, dtype=wp.int32, device=self.device))
                    continue
            elif data.shape != want:
                raise SceneError(f"checkpoint array {name} has shape {data.shape}, this LF run needs {want}")
            cur.assign(wp.array(data, dtype=cur.dtype, device=self.device))
        self.step_index = step
        self.dirty = bool(ckpt.counters["dirty"])
        self._graphs.clear()
        self._seen.clear()
        if step > 0:  # the birth rule queries the grid of the last rebuild: rebuild it from the same points
            self.grid.build(self.pos, self.cand_radius)
        if hist_rows is not None:
            h = self.hist.numpy()
            h[:step] = hist_rows[:step]
            self.hist.assign(h)

    # ------------------------------------------------------------------------------------------- host views

    def history(self) -> dict[str, np.ndarray]:
        """The outputs of the steps done so far, by name (``aca_warp.kernels.lf_record.H_NAMES``), plus ``time`` [s]."""
        h = self.hist.numpy()[: self.step_index]
        out = {n: h[:, k].copy() for k, n in enumerate(H_NAMES)}
        out["time"] = (np.arange(self.step_index) + 1) * self.scene.lf.dt
        return out

    def patches_host(self) -> dict[str, np.ndarray]:
        """Alive patches (in slot order): x, y, area, thick, top, temp, mcap, age, normal_force, power, cell."""
        a = self.alive.numpy() != 0
        names = {"x": "x", "y": "y", "area": "area", "thick": "thick", "top": "top", "temp": "temp", "mcap": "mcap",
                 "age": "age", "normal_force": "patch_fn", "power": "patch_power", "cell": "patch_cell"}  # fmt: skip
        return {k: getattr(self, v).numpy()[a].copy() for k, v in names.items()}

    def inventory(self) -> float:
        """Debris-system mass [kg]: stored + pending debris in the cells + patch mass ρ_p A t + captured mass."""
        d = self.patches_host()
        rho = self.scene.lf.rho_patch
        return float(
            self.cell_store.numpy().sum()
            + self.cell_src.numpy().sum()
            + np.sum(rho * d["area"] * d["thick"])
            + d["mcap"].sum()
        )

    def mass_fluxes(self) -> dict[str, float]:
        """This step's debris fluxes [kg]: ``matrix_in`` (retained matrix debris), ``patch_lost``, ``emitted``."""
        g = self.glob.numpy()
        return {
            "matrix_in": float(g[G_MATRIX_IN]),
            "patch_lost": float(g[G_PATCH_LOST]),
            "emitted": float(g[G_EMITTED]),
        }

    def resolve_overlaps(self, passes: int = 20) -> int:
        """Merge until no two alive patches overlap (before a snapshot); returns the passes used."""
        for k in range(passes):
            d = self.patches_host()
            pt = Patches(d["x"], d["y"], d["area"], np.maximum(d["thick"], 0.0)) if len(d["x"]) else None
            if pt is None or len(overlapping_pairs(pt)) == 0:
                return k
            self.rebuild_neighbours()
            self._group()  # patches born since the last binning keep the cell their slot held (as merges use)
            self.merge()
            self.dirty = True
        raise SceneError("patches still overlap after the merge passes")

    def snapshot(self) -> dict[str, Any]:
        """The patch coverage state for HF hand-off (contact re-solved at this step's load), SI arrays + attrs.

        Elevations include the disc rings' thermal bulge; all heights are shifted by one constant so the lowest
        element sits at 0 (a common shift leaves the contact solution unchanged).
        """
        self.resolve_overlaps()
        self.resolve()
        self.dirty = True
        bulge = self.ring_bulge.numpy()
        d = self.patches_host()
        g = self.glob.numpy()
        n_t = self.n_t
        cell_cover = self.cell_cover.numpy()
        free = np.maximum(self.cell_area_host - cell_cover, 0.0)
        z_cell = self.cell_z.numpy() + np.repeat(bulge, n_t)
        z_patch = d["top"] + bulge[d["cell"] // n_t]
        shift = min(z_cell.min(), z_patch.min() if len(z_patch) else np.inf)
        return {
            "patches": {
                "x": d["x"], "y": d["y"], "area": d["area"], "height": z_patch - shift, "thickness": d["thick"],
                "normal_force": d["normal_force"], "temperature": d["temp"], "age": d["age"], "power": d["power"],
            },
            "matrix": {
                "area": free, "radius": self.cell_rc_host.copy(), "height": z_cell - shift,
                "x": self.cell_x_host.copy(),
                "y": self.cell_y_host.copy(), "normal_force": self.cell_fn.numpy().copy(),
                "temperature": self.cell_T.numpy().copy(), "store": self.cell_store.numpy().copy(),
            },
            "rings": {
                "radius": self.ring_r.numpy().copy(), "temperature": self.ring_T.numpy().copy(), "bulge": bulge.copy(),
            },
            "attrs": {
                "time": self.step_index * self.scene.lf.dt,
                "normal_force": float(g[G_LOAD]),
                "angular_velocity": float(g[G_OMEGA]),
                "gap": float(g[G_GAP] - shift),
                "height_shift": float(shift),
            },
        }  # fmt: skip
