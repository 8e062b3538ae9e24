"""LF automaton (0.01 s steps): patch dynamics, temperatures, wear, debris flow, normal forces (docs/lf_model.md).

Modules: :mod:`~aca_warp.lf.scene` (LF scenes, constants, load schedules, TOML), :mod:`~aca_warp.lf.solver`
(device state and the step sequence; kernels in ``aca_warp.kernels.lf_*``), :mod:`~aca_warp.lf.io` (LF run files,
snapshots, :func:`~aca_warp.lf.io.scene_from_snapshot`), :mod:`~aca_warp.lf.commands` (``aca-warp lf``).
"""
