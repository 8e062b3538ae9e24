"""HF kernels of the error-controlled split step: ``controlled``, and the sticking mode of ``auto``.

The step is ``strang``'s (forced damped midpoint, docs/friction_step.md §6.2) with its own step per pad, chosen from
an error estimate (§5.1, §6.3). A pad on it carries the staggered velocity w in the state's ``v``, the spring force
F_n = F_s(uₙ) in ``state.force`` and F_{n−1} in ``dp5.force_prev``. One trial of step h:

* per patch, the merged sub-step over the span (h_prev + h)/2 (h/2 when h_prev = 0, the opening half step from a
  synchronous state): w⁺ = friction_substep(w, span, F_n), u⁺ = u + h w⁺, and the sub-step's error against the
  trapezoidal rule, e_f = |span (φ(w) + φ(w⁺))/2 − (w⁺ − w)|, φ(v) = (F_n + F_N f(ωr − v) − c v)/m;
* per patch, F⁺ = F_s(u⁺) (the step's one gather);
* per pad, the spring part e_s = h³/12 |F̈|/m of the trapezoidal kick, F̈ = 2 ((F⁺ − F_n)/h − (F_n − F_{n−1})/h_prev)
  / (h + h_prev) (0 without a valid history: after opening, switching or a growth event), and the rms over the pad
  of e_s/(tol_i V_i) (err_s) and of √(e_s² + e_f²)/(tol_i V_i) (err), V_i the pair's velocity scale. err_s ≤ 1
  accepts (the merged sub-step also carries the closing half of the step before, which no shorter trial reduces);
  err sizes the next step: PI for order 2, h · clamp(0.9 err^−0.35 err_prev^0.2, 0.2, 5) (at most 1 after a
  rejection or when err > 1), on rejection h · clamp(0.9 err^−½, 0.2, 1); want ≤ ``dp5.h_max_i`` = min(sample
  interval, 0.9 × the spring bound). The steps of an interval are equal (:func:`~aca_warp.kernels.hf_adaptive.
  even_step`), and every pad lands on every sample (and growth event) time, as the pair's do.

A sample records the synchronous velocity, the closing half sub-step of the state (``strang_close_velocity``),
without changing the staggered state. The per-pad control, landing, counters and checkpointed columns are the
pair's (:mod:`aca_warp.kernels.hf_adaptive`, struct :data:`~aca_warp.kernels.hf_types.HFAdaptive`), with the
trial state in ``dp5.u_a``/``dp5.v_a``.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels import precision_overloads
from aca_warp.kernels.hf import RECORD_FLAG, patch_close_velocity
from aca_warp.kernels.hf_adaptive import (
    C_ERR,
    C_H,
    C_HPREV,
    C_START,
    C_T,
    C_TARGET,
    C_TRIAL,
    M_CALM,
    M_LANDED,
    M_NEEDK1,
    M_REJECTED,
    M_SPLIT,
    M_SWITCH,
    CtlVec,
    ModeVec,
    advance_clock,
    count_trial,
    even_step,
    load_control,
    mark_static,
    store_control,
)
from aca_warp.kernels.hf_types import HFAdaptive, HFModel, HFRecorder
from aca_warp.kernels.physics import friction_substep, patch_force, spring_force

wp.set_module_options({"enable_backward": False})


@wp.func
def split_active(p: int, dp5: Any) -> bool:
    """Whether pad p takes a trial of the split step in this iteration (on it and not landed)."""
    return dp5.mode[p, M_LANDED] == 0 and dp5.mode[p, M_SPLIT] != 0


@wp.func
def split_decide(c: CtlVec, m: ModeVec, err: wp.float64, err_s: wp.float64, h_max: wp.float64, h_min: wp.float64):
    """Accept a trial of the split step when its spring part ``err_s`` ≤ 1, choose the next desired step from the
    full ``err`` (PI for order 2) and the next trial (equal steps to the target): (c, m, accepted, below h_min)."""
    accepted = int(0)
    if not wp.isfinite(err):
        err = wp.float64(1.0e10)
    if not wp.isfinite(err_s):
        err_s = wp.float64(1.0e10)
    h = c[C_TRIAL]
    t = c[C_T]
    e = wp.max(err, wp.float64(1.0e-10))
    if err_s <= wp.float64(1.0):
        fac = wp.float64(0.9) * wp.pow(e, wp.float64(-0.35)) * wp.pow(c[C_ERR], wp.float64(0.2))
        top = wp.float64(5.0)
        if m[M_REJECTED] != 0 or err > wp.float64(1.0):
            top = wp.float64(1.0)
        want = h * wp.clamp(fac, wp.float64(0.2), top)
        m[M_REJECTED] = 0
        m[M_NEEDK1] = 0  # the spring history is valid from here on
        accepted = 1
        c[C_ERR] = wp.max(e, wp.float64(1.0e-4))
        c[C_HPREV] = h
        c, m = advance_clock(c, m, h)
        t = c[C_T]
    else:
        want = h * wp.clamp(wp.float64(0.9) * wp.pow(e, wp.float64(-0.5)), wp.float64(0.2), wp.float64(1.0))
        m[M_REJECTED] = 1
    underflow = int(0)
    if want < h_min:
        underflow = 1
    want = wp.clamp(want, h_min, h_max)
    c[C_H] = want
    if m[M_LANDED] == 0:
        c[C_TRIAL] = even_step(want, t, c[C_TARGET])
    return c, m, accepted, underflow


@wp.func
def forced_rate(v: Any, force: Any, i: int, p: int, model: Any):
    """φ(v) = (F + F_N f(ωr − v) − c v)/m of patch i (pad p) at velocity v [m/s] with spring force F [N], in m/s²."""
    return model.inv_mass[i] * patch_force(
        force, v, model.damping[i], model.normal_force[i], model.pad_omega[p] * model.radius[i],
        model.pad_mu_scale[p], model.pad_slope[p], model.pad_decay[p],
    )  # fmt: skip


@wp.func
def patch_substep(i: int, p: int, v: Any, span: Any, force: Any, model: Any, tol: Any):
    """Patch i's (pad p) damped-midpoint friction sub-step over ``span`` [s] from v [m/s] with the spring force
    ``force`` [N] frozen (:func:`~aca_warp.kernels.physics.friction_substep`)."""
    return friction_substep(
        v, span, type(v)(1.0) / model.inv_mass[i], model.damping[i], model.normal_force[i], force,
        model.pad_omega[p] * model.radius[i], model.pad_mu_scale[p], model.pad_slope[p], model.pad_decay[p], tol, 0,
    )  # fmt: skip


@wp.func
def patch_close(i: int, p: int, w: Any, force: Any, dp5: Any, model: Any, tol: Any):
    """Patch i's (pad p) synchronous velocity [m/s] from its staggered w and F_n
    (:func:`~aca_warp.kernels.physics.strang_close_velocity` over the pad's last step; w itself when there is none)."""
    hp = dp5.ctl[p, C_HPREV]
    if hp <= wp.float64(0.0):
        return w
    return patch_close_velocity(i, p, w, force, type(w)(hp), model, tol, 0)


@wp.kernel
def split_trial(
    model: Any,
    dp5: Any,
    tol: Any,
    # State in (u, staggered w, F_n):
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    force: wp.array[Any],
):
    """The trial state (u⁺, w⁺) into ``dp5.u_a``, ``dp5.v_a`` and the sub-step's error e_f [m/s] into
    ``dp5.err_f``, for every patch of a pad on the split step that has not landed (module docstring)."""
    i = wp.tid()
    p = model.patch_pad[i]
    if not split_active(p, dp5):
        return
    h = dp5.ctl[p, C_TRIAL]
    w = v_in[i]
    f = force[i]
    span = type(w)(wp.float64(0.5) * (dp5.ctl[p, C_HPREV] + h))
    wn = patch_substep(i, p, w, span, f, model, tol)
    dp5.v_a[i] = wn
    dp5.u_a[i] = u_in[i] + type(w)(h) * wn
    half = type(w)(0.5)
    dp5.err_f[i] = wp.abs(span * half * (forced_rate(w, f, i, p, model) + forced_rate(wn, f, i, p, model)) - (wn - w))


@wp.kernel
def split_gather(model: Any, dp5: Any):
    """F⁺ = F_s(u⁺) at the trial state into ``dp5.force_new`` (every patch of a pad taking a split trial)."""
    i = wp.tid()
    if not split_active(model.patch_pad[i], dp5):
        return
    dp5.force_new[i] = spring_force(i, dp5.u_a, model)


@wp.kernel
def split_control(
    model: Any,
    dp5: Any,
    threads: int,
    # State in: F_n
    force: wp.array[Any],
):
    """Per pad on the split step (one block): the trial's scaled errors (rms over the pad), accept or reject, the
    next step, landing (:func:`split_decide`); counted in ``dp5.stats``, a step below ``dp5.h_min`` in
    ``dp5.done[2]``."""
    pad, lane = wp.tid()
    if dp5.mode[pad, M_SPLIT] == 0:
        return
    dp5.accepted[pad] = 0
    if dp5.mode[pad, M_LANDED] != 0:
        return
    a = model.pad_patch_start[pad]
    n = model.pad_patch_start[pad + 1] - a
    h = dp5.ctl[pad, C_TRIAL]
    hp = dp5.ctl[pad, C_HPREV]
    history = dp5.mode[pad, M_NEEDK1] == 0 and hp > wp.float64(0.0)
    part_s = wp.float64(0.0)
    part = wp.float64(0.0)
    i = lane
    while i < n:
        g = a + i
        es = wp.float64(0.0)
        if history:
            fn = wp.float64(force[g])
            dd = ((wp.float64(dp5.force_new[g]) - fn) / h - (fn - wp.float64(dp5.force_prev[g])) / hp) * (
                wp.float64(2.0) / (h + hp)
            )
            es = h * h * h / wp.float64(12.0) * wp.abs(dd) * wp.float64(model.inv_mass[g])
        scale = dp5.tol_i * wp.float64(dp5.v_scale[g])
        xs = es / scale
        xf = wp.float64(dp5.err_f[g]) / scale
        part_s += xs * xs
        part += xs * xs + xf * xf
        i += threads
    sum_s = wp.tile_sum(wp.tile(part_s))[0]
    total = wp.tile_sum(wp.tile(part))[0]
    if lane != 0:
        return
    count = wp.float64(wp.max(n, 1))
    c, m = load_control(pad, dp5)
    err = wp.sqrt(total / count)
    c, m, accepted, underflow = split_decide(c, m, err, wp.sqrt(sum_s / count), dp5.h_max_i, dp5.h_min)
    store_control(pad, c, m, dp5)
    count_trial(pad, accepted, underflow, dp5)
    dp5.accepted[pad] = accepted


@wp.kernel
def split_commit(
    model: Any,
    dp5: Any,
    # State in/out:
    force: wp.array[Any],
    u_io: wp.array[Any],
    v_io: wp.array[Any],
):
    """An accepted split trial becomes the state: (u, w) ← (u⁺, w⁺), F_{n−1} ← F_n, F_n ← F⁺; with
    ``dp5.switching``, a patch on the static branch flags its pad."""
    i = wp.tid()
    p = model.patch_pad[i]
    if dp5.mode[p, M_SPLIT] == 0 or dp5.accepted[p] == 0:
        return
    w = dp5.v_a[i]
    u_io[i] = dp5.u_a[i]
    v_io[i] = w
    dp5.force_prev[i] = force[i]
    force[i] = dp5.force_new[i]
    if dp5.switching != 0:
        mark_static(i, p, w, model, dp5)


@wp.kernel
def split_sample(
    model: Any,
    dp5: Any,
    tol: Any,
    rec: Any,
    event: wp.array[wp.int64],
    # State in/out:
    u_in: wp.array[Any],
    force: wp.array[Any],
    v_io: wp.array[Any],
):
    """After the landing and the growth launches, per patch: at a growth event a split pad's F_n at the grown
    stiffnesses; at a sample the velocity to record into ``dp5.v_rec`` (synchronous: :func:`patch_close` on the split
    step); at a change of integrator (``M_SWITCH``, at a sample) the pair → split step F_n = F_s(u), split step →
    pair the synchronous velocity into the state."""
    i = wp.tid()
    p = model.patch_pad[i]
    sample = rec.counters[RECORD_FLAG] != 0
    grown = event[0] != wp.int64(0)
    switch = dp5.mode[p, M_SWITCH] != 0
    if not (sample or grown or switch):
        return
    if dp5.mode[p, M_SPLIT] != 0:
        if grown:
            force[i] = spring_force(i, u_in, model)
        if sample or switch:
            v = patch_close(i, p, v_io[i], force[i], dp5, model, tol)
            dp5.v_rec[i] = v
            if switch:
                v_io[i] = v
    else:
        if sample:
            dp5.v_rec[i] = v_io[i]
        if switch:
            force[i] = spring_force(i, u_in, model)


@wp.kernel
def switch_done(dp5: Any):
    """Per pad that changes integrator at this sample: the other one from here on, with a fresh controller (first
    step from the synchronous state, no spring history or first stage, no PI memory) keeping its desired step; when
    its interval is open already, its trial is that integrator's."""
    p = wp.tid()
    if dp5.mode[p, M_SWITCH] == 0:
        return
    c, m = load_control(p, dp5)
    m[M_SPLIT] = 1 - m[M_SPLIT]
    m[M_SWITCH] = 0
    m[M_CALM] = 0
    m[M_NEEDK1] = 1
    m[M_REJECTED] = 0
    c[C_HPREV] = wp.float64(0.0)
    c[C_ERR] = wp.float64(1.0e-4)
    if m[M_LANDED] == 0:
        if m[M_SPLIT] != 0:
            c[C_TRIAL] = even_step(c[C_H], c[C_START], c[C_TARGET])
        else:
            c[C_TRIAL] = wp.min(c[C_H], c[C_TARGET] - c[C_START])
    store_control(p, c, m, dp5)


@wp.kernel
def split_finish(
    model: Any,
    dp5: Any,
    tol: Any,
    # State in/out:
    force: wp.array[Any],
    v_io: wp.array[Any],
):
    """At the end of a run, a split pad's staggered w becomes its synchronous velocity (:func:`patch_close`)."""
    i = wp.tid()
    p = model.patch_pad[i]
    if dp5.mode[p, M_SPLIT] == 0:
        return
    v_io[i] = patch_close(i, p, v_io[i], force[i], dp5, model, tol)


precision_overloads(
    split_trial,
    split_gather,
    split_control,
    split_commit,
    split_sample,
    switch_done,
    split_finish,
    model=HFModel,
    dp5=HFAdaptive,
    rec=HFRecorder,
)
