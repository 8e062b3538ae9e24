"""HF kernels of the ``adaptive`` integrator: the Dormand–Prince 5(4) pair with its own step per pad.

DP5 (7 stages, first same as last: 6 right-hand-side evaluations per trial) on y = (u, u̇), u̇ = v,
m v̇ = F_s(u) − c v + F_N f(ωr − v), explicit in every term. Error estimate: the embedded 4th-order solution, the
maximum over the pad's patches of |e_u| / (tol (U_i + |u|)) and |e_v| / (tol w_i), w_i = min(V_i + |u̇|,
M / |f′(s_i)|): U_i the static deflection scale, V_i the velocity scale (the disc speed or the release speed of the
largest friction force), and the friction weight M/|f′| at the trial's slip s_i, which asks every patch's friction
force to be right to tol·F_N M (near sticking a velocity error of M/f′ ≈ 8 mm/s already moves it by F_N M). PI step
control (Gustafsson: k_I = 0.3, k_P = 0.4 over the order 5, factors 0.2–5, no growth right after a rejection);
steps land exactly on the sample times, where every pad waits for the others so that a sample is recorded for all.
In a growing model they land on the growth event times j·interval as well (a target is the earlier of the next
sample and the next event): there the landing sets the event flag that the growth kernels read
(:func:`~aca_warp.kernels.hf.growth_due` with ``every`` = 0) and every pad evaluates its first stage again.

Per-pad control arrays: float64 ``ctl`` (pads, CTL): t, desired step, previous error (PI), target time, start of
the interval, trial step; int32 ``mode`` (pads, MODE): landed, needs its first stage, last trial rejected, index of
the next sample (the target's, or the one after an event target), index of the next growth event; int64 ``stats``
(pads, 2): accepted and rejected trials.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels import precision_overloads
from aca_warp.kernels.physics import friction_pair, patch_force, spring_force

wp.set_module_options({"enable_backward": False})

# ctl columns (float64)
C_T, C_H, C_ERR, C_TARGET, C_START, C_TRIAL = 0, 1, 2, 3, 4, 5
CTL = 6
# mode columns (int32)
M_LANDED, M_NEEDK1, M_REJECTED, M_SAMPLE, M_EVENT = 0, 1, 2, 3, 4
MODE = 5
# an event within this share of the shorter of the sample and event intervals from a sample time is at that time
# (j·interval and k·sample_dt of the same instant differ by a few rounding units)
EVENT_MERGE = 1.0e-9
STAGES = 7

# Dormand–Prince 5(4): a (7×7, row s: the stage-s combination of k_0 … k_{s-1}), e = b − b* (b = a[6], b_7 = 0)
DP5_A = (
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0, 0.0),
    (19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0, 0.0),
    (9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0, 0.0),
    (35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0, 0.0),
)
DP5_E = (
    71.0 / 57600.0,
    0.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
)


@wp.func
def lane_spring_force(
    i: int,
    lane: int,
    threads: int,
    u: wp.array[Any],
    k_diag: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_stiffness: wp.array[Any],
):
    """Elastic force on patch i [N] (:func:`~aca_warp.kernels.physics.spring_force`) from the ``threads`` lanes of its
    block: each lane sums every ``threads``-th link, the block adds the lanes' sums. One lane (a CPU block) sums
    as ``spring_force`` does, so CPU results do not depend on the block size; on CUDA the links of a patch are read
    in parallel instead of in one dependent chain."""
    if threads == 1:
        return spring_force(i, u, k_diag, nbr_start, nbr_index, nbr_stiffness)
    part = u[i] - u[i]
    e = nbr_start[i] + lane
    end = nbr_start[i + 1]
    while e < end:
        part += nbr_stiffness[e] * u[nbr_index[e]]
        e += threads
    return wp.tile_sum(wp.tile(part))[0] - k_diag[i] * u[i]


@wp.func
def stage_state_h(
    i: int,
    stage: int,
    coeff: wp.array2d[wp.float64],
    h: wp.float64,
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
    u_stage: wp.array[Any],
    v_stage: wp.array[Any],
):
    """Patch i's stage state y_s = y_0 + h Σ_{j<s} a_sj k_j at trial step h [s]."""
    hh = type(u_in[i])(h)
    du = u_in[i] - u_in[i]
    dv = du
    for j in range(stage):
        a = type(du)(coeff[stage, j])
        du += a * ku[j, i]
        dv += a * kv[j, i]
    u_stage[i] = u_in[i] + hh * du
    v_stage[i] = v_in[i] + hh * dv


@wp.func
def stage_k(
    i: int,
    p: int,
    stage: int,
    fs: Any,
    inv_mass: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    coeff: wp.array2d[wp.float64],
    h: wp.float64,
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    v_stage: wp.array[Any],
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
    u_next: wp.array[Any],
    v_next: wp.array[Any],
):
    """Patch i's (of pad p) k_s = (u̇, v̇), v̇ = F/m (:func:`~aca_warp.kernels.physics.patch_force`), from its elastic
    force ``fs`` [N] and velocity at the stage state and, for 0 < s < 6, its next stage state y_{s+1} at trial step
    ``h`` [s] into ``u_next``/``v_next``."""
    v = v_stage[i]
    ku[stage, i] = v
    kv[stage, i] = inv_mass[i] * patch_force(
        fs, v, damping[i], normal_force[i], pad_omega[p] * radius[i], pad_mu_scale[p], pad_slope[p], pad_decay[p]
    )
    if stage > 0 and stage + 1 < STAGES:
        stage_state_h(i, stage + 1, coeff, h, u_in, v_in, ku, kv, u_next, v_next)


@wp.func
def stage_state(
    i: int,
    p: int,
    stage: int,
    coeff: wp.array2d[wp.float64],
    ctl: wp.array2d[wp.float64],
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
    u_stage: wp.array[Any],
    v_stage: wp.array[Any],
):
    """Patch i's (of pad p) stage state at the pad's trial step (:func:`stage_state_h`)."""
    stage_state_h(i, stage, coeff, ctl[p, C_TRIAL], u_in, v_in, ku, kv, u_stage, v_stage)


@wp.func
def patch_error(
    g: int,
    pad: int,
    h: wp.float64,
    tol: wp.float64,
    err_coeff: wp.array[wp.float64],
    u_scale: wp.array[Any],
    v_scale: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    u_new: wp.array[Any],
    v_new: wp.array[Any],
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
):
    """Patch g's (of pad ``pad``) scaled error of a trial of step h: max(|e_u| / (tol (U_g + |u|)),
    |e_v| / (tol w_g)) with the friction weight w_g (module docstring); below 1 the patch accepts the trial."""
    eu = wp.float64(0.0)
    ev = wp.float64(0.0)
    for j in range(STAGES):
        e = err_coeff[j]
        eu += e * wp.float64(ku[j, g])
        ev += e * wp.float64(kv[j, g])
    mu_max = wp.float64(pad_mu_scale[pad]) * wp.float64(3.141592653589793)
    vn = v_new[g]
    fv, fd = friction_pair(pad_omega[pad] * radius[g] - vn, pad_mu_scale[pad], pad_slope[pad], pad_decay[pad])
    wv = wp.float64(v_scale[g]) + wp.max(wp.abs(wp.float64(v_in[g])), wp.abs(wp.float64(vn)))
    slope = wp.abs(wp.float64(fd))
    if slope * wv > mu_max:
        wv = mu_max / slope
    su = tol * (wp.float64(u_scale[g]) + wp.max(wp.abs(wp.float64(u_in[g])), wp.abs(wp.float64(u_new[g]))))
    return wp.max(wp.abs(h * eu) / su, wp.abs(h * ev) / (tol * wv))


CtlVec = wp.types.vector(length=CTL, dtype=wp.float64)
ModeVec = wp.types.vector(length=MODE, dtype=wp.int32)


@wp.func
def load_control(p: int, ctl: wp.array2d[wp.float64], mode: wp.array2d[wp.int32]):
    """Pad p's rows of ``ctl`` and ``mode`` as vectors."""
    c = CtlVec()
    m = ModeVec()
    for j in range(CTL):
        c[j] = ctl[p, j]
    for j in range(MODE):
        m[j] = mode[p, j]
    return c, m


@wp.func
def store_control(p: int, c: CtlVec, m: ModeVec, ctl: wp.array2d[wp.float64], mode: wp.array2d[wp.int32]):
    """Vectors ``c`` and ``m`` into pad p's rows of ``ctl`` and ``mode``."""
    for j in range(CTL):
        ctl[p, j] = c[j]
    for j in range(MODE):
        mode[p, j] = m[j]


@wp.func
def pi_decide(c: CtlVec, m: ModeVec, err: wp.float64, h_max: wp.float64, h_min: wp.float64):
    """Accept or reject a trial of scaled error ``err`` of a pad with control ``c`` and mode ``m``, choose its
    next step (PI) and land it on its target: (c, m, accepted, below h_min) after the decision."""
    accepted = int(0)
    if not wp.isfinite(err):
        err = wp.float64(1.0e10)
    h = c[C_TRIAL]
    t = c[C_T]
    target = c[C_TARGET]
    want = c[C_H]
    e = wp.max(err, wp.float64(1.0e-10))
    if err <= wp.float64(1.0):  # PI controller (Gustafsson): k_I = 0.3, k_P = 0.4 over the order 5
        fac = wp.float64(0.9) * wp.pow(e, wp.float64(-0.14)) * wp.pow(c[C_ERR], wp.float64(0.08))
        top = wp.float64(5.0)
        if m[M_REJECTED] != 0:
            top = wp.float64(1.0)
        fac = wp.clamp(fac, wp.float64(0.2), top)
        m[M_REJECTED] = 0
        accepted = 1
        c[C_ERR] = wp.max(e, wp.float64(1.0e-4))
        if h >= want:
            want = h * fac
        else:  # a step cut short to land says nothing against the desired one
            want = wp.max(want, h * fac)
        t = t + h
        if t >= target * (wp.float64(1.0) - wp.float64(1.0e-13)):
            t = target
            m[M_LANDED] = 1
        c[C_T] = t
    else:
        fac = wp.clamp(wp.float64(0.9) * wp.pow(e, wp.float64(-0.2)), wp.float64(0.2), wp.float64(1.0))
        m[M_REJECTED] = 1
        want = h * fac
    underflow = int(0)
    if want < h_min:
        underflow = 1  # the error cannot be met: the run stops with a fault
    want = wp.clamp(want, h_min, h_max)
    c[C_H] = want
    if m[M_LANDED] == 0:
        rest = target - t
        nxt = wp.min(want, rest)
        if rest - nxt < wp.float64(0.01) * nxt:  # no sliver step before the target
            nxt = rest
        c[C_TRIAL] = nxt
    return c, m, accepted, underflow


@wp.func
def count_trial(p: int, accepted: int, underflow: int, stats: wp.array2d[wp.int64], done: wp.array[wp.int32]):
    """Pad p's accepted or rejected trial into ``stats``; a step below the minimum into ``done[2]``."""
    if accepted != 0:
        stats[p, 0] = stats[p, 0] + wp.int64(1)
    else:
        stats[p, 1] = stats[p, 1] + wp.int64(1)
    if underflow != 0:
        done[2] = 1


@wp.func
def pi_control(
    pad: int,
    err: wp.float64,
    h_max: wp.float64,
    h_min: wp.float64,
    ctl: wp.array2d[wp.float64],
    mode: wp.array2d[wp.int32],
    stats: wp.array2d[wp.int64],
    done: wp.array[wp.int32],
) -> int:
    """:func:`pi_decide` on pad ``pad``'s rows of ``ctl`` and ``mode``, counted in ``stats``; returns 1 when the
    trial is accepted. ``done[2]`` flags a step below ``h_min`` (the pad cannot go on)."""
    c, m = load_control(pad, ctl, mode)
    c, m, accepted, underflow = pi_decide(c, m, err, h_max, h_min)
    store_control(pad, c, m, ctl, mode)
    count_trial(pad, accepted, underflow, stats, done)
    return accepted


@wp.func
def open_decide(c: CtlVec, m: ModeVec, sample_dt: wp.float64):
    """A pad landed on its target sample heads for the next one (sample times k·sample_dt, not sums of
    intervals); its first trial is its desired step, at most one interval: (c, m) after."""
    k = m[M_SAMPLE] + 1
    m[M_SAMPLE] = k
    c[C_START] = c[C_TARGET]
    c[C_TARGET] = wp.float64(k) * sample_dt
    c[C_TRIAL] = wp.min(c[C_H], sample_dt)
    m[M_LANDED] = 0
    return c, m


@wp.func
def open_interval(p: int, sample_dt: wp.float64, ctl: wp.array2d[wp.float64], mode: wp.array2d[wp.int32]):
    """:func:`open_decide` on pad p's rows of ``ctl`` and ``mode``."""
    c, m = load_control(p, ctl, mode)
    c, m = open_decide(c, m, sample_dt)
    store_control(p, c, m, ctl, mode)


@wp.func
def merge_width(sample_dt: wp.float64, interval: wp.float64) -> wp.float64:
    """How close [s] an event time must come to a sample time to be at it (:data:`EVENT_MERGE`)."""
    return wp.float64(EVENT_MERGE) * wp.min(sample_dt, interval)


@wp.func
def target_after(m: ModeVec, sample_dt: wp.float64, interval: wp.float64) -> wp.float64:
    """The next target [s] of a pad with mode ``m``: its next sample time k·sample_dt, or its next event time
    j·interval when that comes earlier by more than the merge width (both products of an index, not sums of
    intervals)."""
    ts = wp.float64(m[M_SAMPLE]) * sample_dt
    te = wp.float64(m[M_EVENT]) * interval
    if te < ts - merge_width(sample_dt, interval):
        return te
    return ts


@wp.func
def at_sample(c: CtlVec, m: ModeVec, sample_dt: wp.float64, interval: wp.float64) -> bool:
    """Whether the target of a pad with control ``c`` and mode ``m`` (:func:`target_after`) is its next sample
    time."""
    return c[C_TARGET] >= wp.float64(m[M_SAMPLE]) * sample_dt - merge_width(sample_dt, interval)


@wp.func
def at_event(c: CtlVec, m: ModeVec, sample_dt: wp.float64, interval: wp.float64) -> bool:
    """Whether the target of a pad with control ``c`` and mode ``m`` is its next growth event time (never without
    growth, ``interval`` = 0)."""
    if interval <= wp.float64(0.0):
        return False
    return c[C_TARGET] >= wp.float64(m[M_EVENT]) * interval - merge_width(sample_dt, interval)


@wp.func
def open_growth_decide(c: CtlVec, m: ModeVec, sample_dt: wp.float64, interval: wp.float64):
    """A pad of a growing model, landed on its target (a sample time, an event time or both), moves past what it
    landed on and heads for the next target; its first trial is its desired step, at most the whole interval:
    (c, m) after."""
    sample = at_sample(c, m, sample_dt, interval)
    event = at_event(c, m, sample_dt, interval)
    if sample:
        m[M_SAMPLE] = m[M_SAMPLE] + 1
    if event:
        m[M_EVENT] = m[M_EVENT] + 1
    start = c[C_TARGET]
    target = target_after(m, sample_dt, interval)
    c[C_START] = start
    c[C_TARGET] = target
    c[C_TRIAL] = wp.min(c[C_H], target - start)
    m[M_LANDED] = 0
    return c, m


@wp.func
def on_sample(p: int, sample_dt: wp.float64, interval: wp.float64, ctl: wp.array2d[wp.float64],
              mode: wp.array2d[wp.int32]) -> bool:  # fmt: skip
    """:func:`at_sample` of pad p's rows of ``ctl`` and ``mode``."""
    c, m = load_control(p, ctl, mode)
    return at_sample(c, m, sample_dt, interval)


@wp.func
def on_event(p: int, sample_dt: wp.float64, interval: wp.float64, ctl: wp.array2d[wp.float64],
             mode: wp.array2d[wp.int32]) -> bool:  # fmt: skip
    """:func:`at_event` of pad p's rows of ``ctl`` and ``mode``."""
    c, m = load_control(p, ctl, mode)
    return at_event(c, m, sample_dt, interval)


@wp.func
def open_growth_interval(
    p: int, sample_dt: wp.float64, interval: wp.float64, ctl: wp.array2d[wp.float64], mode: wp.array2d[wp.int32]
):
    """:func:`open_growth_decide` on pad p's rows of ``ctl`` and ``mode``."""
    c, m = load_control(p, ctl, mode)
    c, m = open_growth_decide(c, m, sample_dt, interval)
    store_control(p, c, m, ctl, mode)


@wp.kernel
def dp5_stage(
    # Model:
    patch_pad: wp.array[wp.int32],
    coeff: wp.array2d[wp.float64],
    # Control:
    stage: int,
    ctl: wp.array2d[wp.float64],
    mode: wp.array2d[wp.int32],
    # State in:
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
    # Stage state out:
    u_stage: wp.array[Any],
    v_stage: wp.array[Any],
):
    """The stage state y_s of every patch of a pad that has not landed (:func:`stage_state`)."""
    i = wp.tid()
    p = patch_pad[i]
    if mode[p, M_LANDED] != 0:
        return
    stage_state(i, p, stage, coeff, ctl, u_in, v_in, ku, kv, u_stage, v_stage)


@wp.kernel
def dp5_eval(
    # Model:
    patch_pad: wp.array[wp.int32],
    inv_mass: wp.array[Any],
    k_diag: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_stiffness: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    # Control:
    stage: int,
    first: int,
    threads: int,
    mode: wp.array2d[wp.int32],
    # Stage state in:
    u_stage: wp.array[Any],
    v_stage: wp.array[Any],
    # Out:
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
    # Next stage (stage > 0 and stage + 1 < STAGES): y_0, the coefficients and the next stage state's buffers
    coeff: wp.array2d[wp.float64],
    ctl: wp.array2d[wp.float64],
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    u_next: wp.array[Any],
    v_next: wp.array[Any],
):
    """k_s = (u̇, v̇) at the stage state of every pad that has not landed; ``first``: k_0 of the pads that need it
    (at the start), at the state itself. For 0 < s < 6 also the patch's next stage state y_{s+1} (:func:`stage_state`)
    into ``u_next``/``v_next``, which must not be ``u_stage``/``v_stage``: the neighbours still read those.
    One block of ``threads`` lanes per patch (``launch_tiled``; :func:`lane_spring_force`)."""
    i, lane = wp.tid()
    p = patch_pad[i]
    if mode[p, M_LANDED] != 0:
        return
    if first != 0 and mode[p, M_NEEDK1] == 0:
        return
    fs = lane_spring_force(i, lane, threads, u_stage, k_diag, nbr_start, nbr_index, nbr_stiffness)
    if lane != 0:
        return
    stage_k(
        i, p, stage, fs, inv_mass, damping, normal_force, radius, pad_omega, pad_mu_scale, pad_slope, pad_decay, coeff,
        ctl[p, C_TRIAL], u_in, v_in, v_stage, ku, kv, u_next, v_next,
    )  # fmt: skip


@wp.kernel
def dp5_control(
    # Model:
    pad_patch_start: wp.array[wp.int32],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    err_coeff: wp.array[wp.float64],
    u_scale: wp.array[Any],
    v_scale: wp.array[Any],
    threads: int,
    tol: wp.float64,
    h_max: wp.float64,
    h_min: wp.float64,
    # State in (y_0, the 5th-order solution = stage 7, the stages):
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    u_new: wp.array[Any],
    v_new: wp.array[Any],
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
    # Control in/out:
    ctl: wp.array2d[wp.float64],
    mode: wp.array2d[wp.int32],
    stats: wp.array2d[wp.int64],
    accepted: wp.array[wp.int32],
    done: wp.array[wp.int32],
):
    """Per pad (one block): the trial's scaled error (maximum over the pad), accept or reject, next step (PI),
    landing on the target; ``done[1]`` flags a step below ``h_min`` (the pad cannot go on)."""
    pad, lane = wp.tid()
    accepted[pad] = 0
    if mode[pad, M_LANDED] != 0:
        return
    a = pad_patch_start[pad]
    n = pad_patch_start[pad + 1] - a
    h = ctl[pad, C_TRIAL]
    part = wp.float64(0.0)
    i = lane
    while i < n:
        g = a + i
        e = patch_error(g, pad, h, tol, err_coeff, u_scale, v_scale, radius, pad_omega, pad_mu_scale, pad_slope,
                        pad_decay, u_in, v_in, u_new, v_new, ku, kv)  # fmt: skip
        part = wp.max(part, e)
        i += threads
    err = wp.tile_max(wp.tile(part))[0]
    if lane != 0:
        return
    accepted[pad] = pi_control(pad, err, h_max, h_min, ctl, mode, stats, done)


@wp.kernel
def dp5_commit(
    patch_pad: wp.array[wp.int32],
    accepted: wp.array[wp.int32],
    # Trial in:
    u_new: wp.array[Any],
    v_new: wp.array[Any],
    # State and stages out:
    u_io: wp.array[Any],
    v_io: wp.array[Any],
    ku: wp.array2d[Any],
    kv: wp.array2d[Any],
):
    """An accepted trial becomes the state; its last stage becomes the next first one (FSAL)."""
    i = wp.tid()
    if accepted[patch_pad[i]] == 0:
        return
    u_io[i] = u_new[i]
    v_io[i] = v_new[i]
    ku[0, i] = ku[STAGES - 1, i]
    kv[0, i] = kv[STAGES - 1, i]


@wp.kernel
def landing(
    pads: int,
    sample_dt: wp.float64,
    interval: wp.float64,
    t_end: wp.float64,
    t_stop: wp.array[wp.float64],
    # Control in/out:
    ctl: wp.array2d[wp.float64],
    mode: wp.array2d[wp.int32],
    done: wp.array[wp.int32],
    counters: wp.array[wp.int32],
    event: wp.array[wp.int64],
):
    """One thread: when every pad has landed on its target, flag a growth event there (``event[0]``, with every
    pad's first stage due again; growing models, ``interval`` > 0) and a sample there (``counters[3]``); the growth
    launches and then the recorder follow in the same iteration, so a sample at an event time sees the grown
    patches, as on the fixed-step path. Then, unless the run is over or stopped (``done[0]``, ``done[2]``: a step
    underflow) or the host asked to pause at this sample (``t_stop[0]``; ``done[1]`` waits until it is moved on),
    open every pad's next interval."""
    counters[3] = 0
    event[0] = wp.int64(0)
    if done[0] != 0 or done[2] != 0:
        return
    if done[1] == 0:
        for p in range(pads):
            if mode[p, M_LANDED] == 0:
                return
        if on_event(0, sample_dt, interval, ctl, mode):
            event[0] = wp.int64(1)
            for p in range(pads):
                mode[p, M_NEEDK1] = 1  # k_0 (FSAL) was evaluated with the model before the event
        if not on_sample(0, sample_dt, interval, ctl, mode):
            for p in range(pads):
                open_growth_interval(p, sample_dt, interval, ctl, mode)
            return
        counters[3] = 1
        if ctl[0, C_TARGET] >= t_end * (wp.float64(1.0) - wp.float64(1.0e-12)):
            done[0] = 1
            return
        if ctl[0, C_TARGET] >= t_stop[0] * (wp.float64(1.0) - wp.float64(1.0e-12)):
            done[1] = 1
            return
    elif ctl[0, C_TARGET] >= t_stop[0] * (wp.float64(1.0) - wp.float64(1.0e-12)):
        return
    done[1] = 0
    for p in range(pads):
        if interval > wp.float64(0.0):
            open_growth_interval(p, sample_dt, interval, ctl, mode)
        else:
            open_interval(p, sample_dt, ctl, mode)


@wp.kernel
def k1_done(mode: wp.array2d[wp.int32]):
    """Per pad: its first stage is evaluated."""
    p = wp.tid()
    mode[p, M_NEEDK1] = 0


precision_overloads(dp5_stage, dp5_eval, dp5_control, dp5_commit)
