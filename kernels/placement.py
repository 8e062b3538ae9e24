"""Random sequential addition of discs on a pad: the sequential loop of the patch generator as one native thread.

The trials (positions, their distances to the pad's bounds) are drawn on the host in the generator's order
(``aca_warp.scene.generator``); :func:`place_discs` runs the accept / reject loop over them on the CPU, where
:class:`aca_warp.scene.generator.PatchGenerator` ran it in Python. The decisions are the Python loop's, bit for bit:

* a trial lies inside the pad by the comparisons of ``Pad.disc_fits``, with the same operands (differences, sums and
  products of two doubles, each rounded once: no contraction applies);
* a trial overlaps a placed disc j when ``hypot(dx, dy) < r_i + r_j`` in the Python loop. The kernel compares
  d² = dx² + dy² with s² = (r_i + r_j)², whose roundings (and a fused multiply-add the compiler may form) part from
  the exact values by a few units in the last place; where d² lies within the relative ``margin`` of s² it does not
  decide but stops (status :data:`AMBIGUOUS`) and the host decides that trial with ``math.hypot``, as the Python
  loop did, then resumes. Outside the margin both comparisons agree.

The placed discs sit in a hashed grid of cells of width ``cell`` (≥ the largest diameter): a trial is tested against
the chains of the 3 × 3 cells around its own, as the Python loop tested the discs of those cells; a chain may also
hold discs of other cells whose hash collides, which lie too far to overlap and change no decision.
"""

from __future__ import annotations

import numpy as np
import warp as wp

wp.set_module_options({"enable_backward": False})

# Status of a launch (``state[3]``).
DONE = 0  # every disc placed
MORE_TRIALS = 1  # the trials ran out: draw more and resume
NOT_PLACED = 2  # a disc found no place within its tries
AMBIGUOUS = 3  # a trial's overlap test lies within the margin: the host decides it (``state[4]``) and resumes

# ``state[4]``: the host's decision for the trial at ``state[1]``.
UNDECIDED = 0
ACCEPT = 1
REJECT = 2

STATE_SIZE = 5  # placed discs i, next trial k, tries of disc i, status, decision

MARGIN = 1e-10  # relative band of d² around s² that the kernel leaves to the host: ≫ its roundings (≈ 1e-15)


@wp.func
def _bucket(cx: int, cy: int, mask: wp.uint32) -> int:
    """The hash bucket of cell (cx, cy) (unsigned arithmetic: wraps, defined for negative cells)."""
    h = (wp.uint32(cx) * wp.uint32(73856093)) ^ (wp.uint32(cy) * wp.uint32(19349663))
    return int(h & mask)


@wp.kernel
def _place(
    # Trials, in draw order:
    tx: wp.array[wp.float64],
    ty: wp.array[wp.float64],
    t_dist: wp.array[wp.float64],
    t_edge: wp.array[wp.float64],
    n_trials: int,
    # Discs and pad:
    radius: wp.array[wp.float64],
    cell: wp.float64,
    inner: wp.float64,
    outer: wp.float64,
    shrink: wp.float64,
    margin: wp.float64,
    max_tries: int,
    mask: wp.uint32,
    # In/out:
    head: wp.array[wp.int32],
    chain: wp.array[wp.int32],
    x: wp.array[wp.float64],
    y: wp.array[wp.float64],
    state: wp.array[wp.int32],
):
    """One thread: place discs ``state[0]`` … from trial ``state[1]`` on; the state and status back into ``state``."""
    count = radius.shape[0]
    i = state[0]
    k = state[1]
    tries = state[2]
    decision = state[4]
    status = int(DONE)
    lo = wp.float64(1.0) - margin
    hi = wp.float64(1.0) + margin
    while i < count:
        if tries >= max_tries:
            status = NOT_PLACED
            break
        if k == n_trials:
            status = MORE_TRIALS
            break
        px = tx[k]
        py = ty[k]
        ri = radius[i]
        r = t_dist[k]
        inside = (r - ri >= inner) and (r + ri <= outer) and (t_edge[k] >= ri * shrink)
        cx = int(wp.floor(px / cell))
        cy = int(wp.floor(py / cell))
        verdict = int(ACCEPT)
        if not inside:
            verdict = REJECT
        elif decision != UNDECIDED:
            verdict = decision
        else:
            for gx in range(cx - 1, cx + 2):
                for gy in range(cy - 1, cy + 2):
                    j = head[_bucket(gx, gy, mask)]
                    while j >= 0 and verdict != REJECT:
                        dx = px - x[j]
                        dy = py - y[j]
                        s = ri + radius[j]
                        d2 = dx * dx + dy * dy
                        s2 = s * s
                        if d2 < s2 * lo:
                            verdict = REJECT
                        elif d2 <= s2 * hi:
                            verdict = UNDECIDED
                        j = chain[j]
            if verdict == UNDECIDED:
                status = AMBIGUOUS
                break
        decision = UNDECIDED
        k += 1
        tries += 1
        if verdict == ACCEPT:
            x[i] = px
            y[i] = py
            b = _bucket(cx, cy, mask)
            chain[i] = head[b]
            head[b] = i
            i += 1
            tries = 0
    state[0] = i
    state[1] = k
    state[2] = tries
    state[3] = status
    state[4] = decision


class DiscPlacement:
    """The accept / reject loop's state on the CPU for ``radius`` (count,) [m]: the placed centres, the hashed grid
    and the counters; :meth:`run` continues it over the trials given."""

    def __init__(self, radius: np.ndarray, cell: float, bounds: tuple[float, float, float]):
        """``bounds``: (inner, outer, shrink), the operands of ``Pad.disc_fits`` (r_inner (1 − 1e-12),
        r_outer (1 + 1e-12), 1 − 1e-12); the band left to the host is :data:`MARGIN`."""
        count = len(radius)
        buckets = 1 << max(int(2 * count - 1).bit_length(), 4)  # ≥ 2 buckets per disc
        self.radius = wp.array(np.asarray(radius, dtype=np.float64), dtype=wp.float64, device="cpu")
        self.head = wp.full(buckets, -1, dtype=wp.int32, device="cpu")
        self.chain = wp.full(count, -1, dtype=wp.int32, device="cpu")
        self.x = wp.zeros(count, dtype=wp.float64, device="cpu")
        self.y = wp.zeros(count, dtype=wp.float64, device="cpu")
        self.state = wp.zeros(STATE_SIZE, dtype=wp.int32, device="cpu")
        self.params = [cell, *bounds, MARGIN]
        self.mask = wp.uint32(buckets - 1)

    def run(self, tx: np.ndarray, ty: np.ndarray, dist: np.ndarray, edge: np.ndarray, max_tries: int) -> np.ndarray:
        """Continue over the trials (n,) given (all drawn so far, in order; the loop resumes at its next one);
        returns the state: placed discs, next trial, tries of the current disc, status, decision."""
        trials = [
            wp.array(np.ascontiguousarray(a, np.float64), dtype=wp.float64, device="cpu") for a in (tx, ty, dist, edge)
        ]
        wp.launch(
            _place,
            dim=1,
            inputs=[*trials, len(tx), self.radius, *self.params, max_tries, self.mask],
            outputs=[self.head, self.chain, self.x, self.y, self.state],
            device="cpu",
        )
        return self.state.numpy().copy()

    def decide(self, accept: bool) -> None:
        """The host's decision for the trial the loop stopped at (status :data:`AMBIGUOUS`)."""
        s = self.state.numpy()
        s[4] = ACCEPT if accept else REJECT
        self.state.assign(s)

    def placed(self) -> tuple[np.ndarray, np.ndarray]:
        """The centres placed so far [m], each shape (placed,)."""
        n = int(self.state.numpy()[0])
        return self.x.numpy()[:n].copy(), self.y.numpy()[:n].copy()
