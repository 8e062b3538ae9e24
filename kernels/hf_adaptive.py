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

The integrator's arrays come to the kernels as one struct, ``dp5`` (:data:`~aca_warp.kernels.hf_types.HFAdaptive`).
Per-pad control: float64 ``dp5.ctl`` (pads, CTL): t, desired step, previous error (PI), target time, start of the
interval, trial step, the last accepted step (the split step's h_prev; 0: none since the state was synchronous);
int32 ``dp5.mode`` (pads, MODE): landed, needs its first stage (a split-step pad: its spring history is not valid),
last trial rejected, index of the next sample (the target's, or the one after an event target), index of the next
growth event, steps with the split step (:mod:`aca_warp.kernels.hf_controlled`) instead of the pair, a patch was on
the static branch at an accepted step of the interval, calm intervals in a row (none on it), changes integrator at
this sample; int64 ``dp5.stats`` (pads, 2): accepted and rejected trials. The kernels here act on the pads that step
with the pair only.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels import precision_overloads
from aca_warp.kernels.hf import RECORD_FLAG
from aca_warp.kernels.hf_types import HFAdaptive, HFModel, HFRecorder
from aca_warp.kernels.physics import friction_pair, patch_force, spring_force

wp.set_module_options({"enable_backward": False})

# ctl columns (float64)
C_T, C_H, C_ERR, C_TARGET, C_START, C_TRIAL, C_HPREV = 0, 1, 2, 3, 4, 5, 6
CTL = 7
# mode columns (int32)
M_LANDED, M_NEEDK1, M_REJECTED, M_SAMPLE, M_EVENT, M_SPLIT, M_STATIC, M_CALM, M_SWITCH = 0, 1, 2, 3, 4, 5, 6, 7, 8
MODE = 9
STATIC_SLIP = 0.17  # m/s: Eq. 4 peaks here; a patch slipping less is on its static branch (sticking)
RELEASE = 50  # calm sample intervals in a row before a pad of ``auto`` returns from the split step to the pair
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
def lane_spring_force(i: int, lane: int, threads: int, u: wp.array[Any], model: Any):
    """Elastic force on patch i [N] (:func:`~aca_warp.kernels.physics.spring_force`) from the ``threads`` lanes of its
    block: each lane sums every ``threads``-th link, the block adds the lanes' sums. One lane (a CPU block) sums
    as ``spring_force`` does, so CPU results do not depend on the block size; on CUDA the links of a patch are read
    in parallel instead of in one dependent chain."""
    if threads == 1:
        return spring_force(i, u, model)
    part = u[i] - u[i]
    e = model.nbr_start[i] + lane
    end = model.nbr_start[i + 1]
    while e < end:
        part += model.nbr_stiffness[e] * u[model.nbr_index[e]]
        e += threads
    return wp.tile_sum(wp.tile(part))[0] - model.k_diag[i] * u[i]


@wp.func
def stage_state_h(
    i: int, stage: int, dp5: Any, h: wp.float64, u_in: wp.array[Any], v_in: wp.array[Any], u_stage: wp.array[Any],
    v_stage: wp.array[Any],
):  # fmt: skip
    """Patch i's stage state y_s = y_0 + h Σ_{j<s} a_sj k_j at trial step h [s] (the stages k_j of ``dp5``)."""
    hh = type(u_in[i])(h)
    du = u_in[i] - u_in[i]
    dv = du
    for j in range(stage):
        a = type(du)(dp5.coeff[stage, j])
        du += a * dp5.ku[j, i]
        dv += a * dp5.kv[j, i]
    u_stage[i] = u_in[i] + hh * du
    v_stage[i] = v_in[i] + hh * dv


@wp.func
def stage_k(
    i: int,
    p: int,
    stage: int,
    fs: Any,
    model: Any,
    dp5: Any,
    h: wp.float64,
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    v_stage: wp.array[Any],
    u_next: wp.array[Any],
    v_next: wp.array[Any],
):
    """Patch i's (of pad p) k_s = (u̇, v̇), v̇ = F/m (:func:`~aca_warp.kernels.physics.patch_force`), from its elastic
    force ``fs`` [N] and velocity at the stage state and, for 0 < s < 6, its next stage state y_{s+1} at trial step
    ``h`` [s] into ``u_next``/``v_next`` (k_s into the stages of ``dp5``)."""
    v = v_stage[i]
    dp5.ku[stage, i] = v
    dp5.kv[stage, i] = model.inv_mass[i] * patch_force(
        fs, v, model.damping[i], model.normal_force[i], model.pad_omega[p] * model.radius[i], model.pad_mu_scale[p],
        model.pad_slope[p], model.pad_decay[p],
    )  # fmt: skip
    if stage > 0 and stage + 1 < STAGES:
        stage_state_h(i, stage + 1, dp5, h, u_in, v_in, u_next, v_next)


@wp.func
def stage_state(
    i: int, p: int, stage: int, dp5: Any, u_in: wp.array[Any], v_in: wp.array[Any], u_stage: wp.array[Any],
    v_stage: wp.array[Any],
):  # fmt: skip
    """Patch i's (of pad p) stage state at the pad's trial step (:func:`stage_state_h`)."""
    stage_state_h(i, stage, dp5, dp5.ctl[p, C_TRIAL], u_in, v_in, u_stage, v_stage)


@wp.func
def patch_error(
    g: int,
    pad: int,
    h: wp.float64,
    model: Any,
    dp5: Any,
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    u_new: wp.array[Any],
    v_new: wp.array[Any],
):
    """Patch g's (of pad ``pad``) scaled error of a trial of step h: max(|e_u| / (tol (U_g + |u|)),
    |e_v| / (tol w_g)) with the friction weight w_g (module docstring); below 1 the patch accepts the trial."""
    tol = dp5.tol
    eu = wp.float64(0.0)
    ev = wp.float64(0.0)
    for j in range(STAGES):
        e = dp5.err_coeff[j]
        eu += e * wp.float64(dp5.ku[j, g])
        ev += e * wp.float64(dp5.kv[j, g])
    mu_max = wp.float64(model.pad_mu_scale[pad]) * wp.float64(3.141592653589793)
    vn = v_new[g]
    fv, fd = friction_pair(
        model.pad_omega[pad] * model.radius[g] - vn, model.pad_mu_scale[pad], model.pad_slope[pad], model.pad_decay[pad]
    )
    wv = wp.float64(dp5.v_scale[g]) + wp.max(wp.abs(wp.float64(v_in[g])), wp.abs(wp.float64(vn)))
    slope = wp.abs(wp.float64(fd))
    if slope * wv > mu_max:
        wv = mu_max / slope
    su = tol * (wp.float64(dp5.u_scale[g]) + wp.max(wp.abs(wp.float64(u_in[g])), wp.abs(wp.float64(u_new[g]))))
    return wp.max(wp.abs(h * eu) / su, wp.abs(h * ev) / (tol * wv))


CtlVec = wp.types.vector(length=CTL, dtype=wp.float64)
ModeVec = wp.types.vector(length=MODE, dtype=wp.int32)


@wp.func
def load_control(p: int, dp5: Any):
    """Pad p's rows of ``dp5.ctl`` and ``dp5.mode`` as vectors."""
    c = CtlVec()
    m = ModeVec()
    for j in range(CTL):
        c[j] = dp5.ctl[p, j]
    for j in range(MODE):
        m[j] = dp5.mode[p, j]
    return c, m


@wp.func
def store_control(p: int, c: CtlVec, m: ModeVec, dp5: Any):
    """Vectors ``c`` and ``m`` into pad p's rows of ``dp5.ctl`` and ``dp5.mode``."""
    for j in range(CTL):
        dp5.ctl[p, j] = c[j]
    for j in range(MODE):
        dp5.mode[p, j] = m[j]


@wp.func
def advance_clock(c: CtlVec, m: ModeVec, h: wp.float64):
    """An accepted step h [s] moves the pad's clock ``c[C_T]``; within a rounding share of its target it stands on
    the target, landed: (c, m) after."""
    t = c[C_T] + h
    if t >= c[C_TARGET] * (wp.float64(1.0) - wp.float64(1.0e-13)):
        t = c[C_TARGET]
        m[M_LANDED] = 1
    c[C_T] = t
    return c, m


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
        c, m = advance_clock(c, m, h)
        t = c[C_T]
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
def count_trial(p: int, accepted: int, underflow: int, dp5: Any):
    """Pad p's accepted or rejected trial into ``dp5.stats``; a step below the minimum into ``dp5.done[2]``."""
    if accepted != 0:
        dp5.stats[p, 0] = dp5.stats[p, 0] + wp.int64(1)
    else:
        dp5.stats[p, 1] = dp5.stats[p, 1] + wp.int64(1)
    if underflow != 0:
        dp5.done[2] = 1


@wp.func
def pi_control(pad: int, err: wp.float64, dp5: Any) -> int:
    """:func:`pi_decide` on pad ``pad``'s rows of ``dp5.ctl`` and ``dp5.mode``, counted in ``dp5.stats``; returns 1
    when the trial is accepted. ``dp5.done[2]`` flags a step below ``dp5.h_min`` (the pad cannot go on)."""
    c, m = load_control(pad, dp5)
    c, m, accepted, underflow = pi_decide(c, m, err, dp5.h_max, dp5.h_min)
    store_control(pad, c, m, dp5)
    count_trial(pad, accepted, underflow, dp5)
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
def even_step(want: wp.float64, t: wp.float64, target: wp.float64) -> wp.float64:
    """The split step's next trial [s]: the rest of the interval from t to the target in equal steps no longer than
    ``want``, rest / ⌈rest / want⌉ (cutting one step short to land repeats a long-short pattern every interval,
    which pumps the pad's highest network mode: docs/friction_step.md §5.1)."""
    rest = target - t
    k = wp.ceil(rest / want - wp.float64(1.0e-9))
    return rest / wp.max(k, wp.float64(1.0))


@wp.func
def pair_active(p: int, dp5: Any) -> bool:
    """Whether pad p takes a trial of the explicit pair in this iteration (not landed, not on the split step)."""
    return dp5.mode[p, M_LANDED] == 0 and dp5.mode[p, M_SPLIT] == 0


@wp.func
def open_next(p: int, dp5: Any):
    """Pad p, landed, heads for its next target on its rows of ``dp5.ctl`` and ``dp5.mode``:
    :func:`open_growth_decide` in a growing model (``dp5.interval`` > 0), else :func:`open_decide`."""
    c, m = load_control(p, dp5)
    if dp5.interval > wp.float64(0.0):
        c, m = open_growth_decide(c, m, dp5.sample_dt, dp5.interval)
    else:
        c, m = open_decide(c, m, dp5.sample_dt)
    if m[M_SPLIT] != 0:
        c[C_TRIAL] = even_step(c[C_H], c[C_START], c[C_TARGET])
    store_control(p, c, m, dp5)


@wp.func
def mark_static(i: int, p: int, v: Any, model: Any, dp5: Any):
    """Flag pad p (``M_STATIC``) when patch i at velocity v [m/s] is on the static branch, |ω r − v| < STATIC_SLIP."""
    if wp.abs(model.pad_omega[p] * model.radius[i] - v) < type(v)(STATIC_SLIP):
        dp5.mode[p, M_STATIC] = 1


@wp.func
def switch_decide(m: ModeVec) -> ModeVec:
    """At a sample, a pad of ``auto`` with mode ``m``: count its calm intervals (no patch on the static branch) and
    flag a change of integrator (``M_SWITCH``): the pair → the split step once a patch touched the static branch,
    back after RELEASE calm intervals."""
    calm = m[M_CALM] + 1
    if m[M_STATIC] != 0:
        calm = 0
    if (m[M_SPLIT] == 0 and m[M_STATIC] != 0) or (m[M_SPLIT] != 0 and calm >= RELEASE):
        m[M_SWITCH] = 1
    m[M_CALM] = calm
    m[M_STATIC] = 0
    return m


@wp.func
def commit_patch(
    i: int, dp5: Any, u_new: wp.array[Any], v_new: wp.array[Any], u_io: wp.array[Any], v_io: wp.array[Any]
):
    """Patch i's accepted trial (``u_new``, ``v_new``) becomes its state; its last stage becomes the next first one
    (FSAL)."""
    u_io[i] = u_new[i]
    v_io[i] = v_new[i]
    dp5.ku[0, i] = dp5.ku[STAGES - 1, i]
    dp5.kv[0, i] = dp5.kv[STAGES - 1, i]


@wp.kernel
def dp5_stage(
    model: Any,
    dp5: Any,
    stage: int,
    # State in:
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    # Stage state out:
    u_stage: wp.array[Any],
    v_stage: wp.array[Any],
):
    """The stage state y_s of every patch of a pad that has not landed (:func:`stage_state`)."""
    i = wp.tid()
    p = model.patch_pad[i]
    if not pair_active(p, dp5):
        return
    stage_state(i, p, stage, dp5, u_in, v_in, u_stage, v_stage)


@wp.kernel
def dp5_eval(
    model: Any,
    dp5: Any,
    stage: int,
    first: int,
    threads: int,
    # Stage state in:
    u_stage: wp.array[Any],
    v_stage: wp.array[Any],
    # Next stage (stage > 0 and stage + 1 < STAGES): y_0 and the next stage state's buffers
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
    p = model.patch_pad[i]
    if not pair_active(p, dp5):
        return
    if first != 0 and dp5.mode[p, M_NEEDK1] == 0:
        return
    fs = lane_spring_force(i, lane, threads, u_stage, model)
    if lane != 0:
        return
    stage_k(i, p, stage, fs, model, dp5, dp5.ctl[p, C_TRIAL], u_in, v_in, v_stage, u_next, v_next)


@wp.kernel
def dp5_control(
    model: Any,
    dp5: Any,
    threads: int,
    # State in (y_0, the 5th-order solution = stage 7):
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    u_new: wp.array[Any],
    v_new: wp.array[Any],
):
    """Per pad (one block): the trial's scaled error (maximum over the pad), accept or reject, next step (PI),
    landing on the target; ``dp5.done[2]`` flags a step below ``dp5.h_min`` (the pad cannot go on)."""
    pad, lane = wp.tid()
    if dp5.mode[pad, M_SPLIT] != 0:
        return
    dp5.accepted[pad] = 0
    if dp5.mode[pad, M_LANDED] != 0:
        return
    a = model.pad_patch_start[pad]
    n = model.pad_patch_start[pad + 1] - a
    h = dp5.ctl[pad, C_TRIAL]
    part = wp.float64(0.0)
    i = lane
    while i < n:
        g = a + i
        e = patch_error(g, pad, h, model, dp5, u_in, v_in, u_new, v_new)
        part = wp.max(part, e)
        i += threads
    err = wp.tile_max(wp.tile(part))[0]
    if lane != 0:
        return
    dp5.accepted[pad] = pi_control(pad, err, dp5)


@wp.kernel
def dp5_commit(
    model: Any,
    dp5: Any,
    # Trial in:
    u_new: wp.array[Any],
    v_new: wp.array[Any],
    # State out:
    u_io: wp.array[Any],
    v_io: wp.array[Any],
):
    """An accepted trial becomes the state; its last stage becomes the next first one (:func:`commit_patch`). With
    ``dp5.switching``, a patch on the static branch flags its pad (:func:`mark_static`)."""
    i = wp.tid()
    p = model.patch_pad[i]
    if dp5.mode[p, M_SPLIT] != 0 or dp5.accepted[p] == 0:
        return
    commit_patch(i, dp5, u_new, v_new, u_io, v_io)
    if dp5.switching != 0:
        mark_static(i, p, v_new[i], model, dp5)


@wp.kernel
def landing(
    pads: int,
    dp5: Any,
    # Recorder and growth flags out:
    rec: Any,
    event: wp.array[wp.int64],
):
    """One thread: when every pad has landed on its target, flag a growth event there (``event[0]``, with every
    pad's first stage due again; growing models, ``dp5.interval`` > 0) and a sample there (the recorder's
    RECORD_FLAG counter); the growth launches and then the recorder follow in the same iteration, so a sample at an
    event time sees the grown patches, as on the fixed-step path. At a sample of ``auto`` (``dp5.switching``),
    every pad's change of integrator is decided (:func:`switch_decide`). Then, unless the run is over or stopped
    (``dp5.done[0]``, ``dp5.done[2]``: a step underflow) or the host asked to pause at this sample
    (``dp5.t_stop[0]``; ``dp5.done[1]`` waits until it is moved on), open every pad's next interval."""
    rec.counters[RECORD_FLAG] = 0
    event[0] = wp.int64(0)
    if dp5.done[0] != 0 or dp5.done[2] != 0:
        return
    if dp5.done[1] == 0:
        for p in range(pads):
            if dp5.mode[p, M_LANDED] == 0:
                return
        c, m = load_control(0, dp5)  # every pad stands on the same target
        if at_event(c, m, dp5.sample_dt, dp5.interval):
            event[0] = wp.int64(1)
            for p in range(pads):
                dp5.mode[p, M_NEEDK1] = 1  # k_0 (FSAL) was evaluated with the model before the event
        if not at_sample(c, m, dp5.sample_dt, dp5.interval):
            for p in range(pads):
                open_next(p, dp5)
            return
        rec.counters[RECORD_FLAG] = 1
        if dp5.switching != 0:
            for p in range(pads):
                cp, mp = load_control(p, dp5)
                store_control(p, cp, switch_decide(mp), dp5)
        if dp5.ctl[0, C_TARGET] >= dp5.t_end * (wp.float64(1.0) - wp.float64(1.0e-12)):
            dp5.done[0] = 1
            return
        if dp5.ctl[0, C_TARGET] >= dp5.t_stop[0] * (wp.float64(1.0) - wp.float64(1.0e-12)):
            dp5.done[1] = 1
            return
    elif dp5.ctl[0, C_TARGET] >= dp5.t_stop[0] * (wp.float64(1.0) - wp.float64(1.0e-12)):
        return
    dp5.done[1] = 0
    for p in range(pads):
        open_next(p, dp5)


@wp.kernel
def k1_done(dp5: Any):
    """Per pad that took this iteration's trial of the pair: its first stage is evaluated (a landed pad, waiting at
    a pause of the run, keeps its flag: after a growth event there its k_0 is still due)."""
    p = wp.tid()
    if pair_active(p, dp5):
        dp5.mode[p, M_NEEDK1] = 0


precision_overloads(
    dp5_stage, dp5_eval, dp5_control, dp5_commit, landing, k1_done, model=HFModel, dp5=HFAdaptive, rec=HFRecorder
)
