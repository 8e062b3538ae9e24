"""argparse value types shared by the ``aca-warp`` commands: one clear error per bad number."""

from __future__ import annotations

import argparse
import math


def number(text: str) -> float:
    """A finite float."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"not a number: {text!r} (a plain number in SI units, e.g. 1e-3 for 1 ms, 5e-8 for 50 ns)"
        ) from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return v


def positive(text: str) -> float:
    """A finite float > 0."""
    v = number(text)
    if not v > 0:
        raise argparse.ArgumentTypeError(f"must be positive (> 0), got {text!r}")
    return v


def step_or_default(text: str) -> float | None:
    """A fixed step: a finite float > 0 [s], or ``default`` (None: strang's default step for the scene)."""
    return None if text == "default" else positive(text)


def spacing(text: str) -> float | str:
    """A growth events' spacing: a finite float > 0 [s], or ``scene`` (the scenes' own growth interval)."""
    if text == "scene":
        return text
    try:
        return positive(text)
    except argparse.ArgumentTypeError as e:
        raise argparse.ArgumentTypeError(f"a spacing in seconds or 'scene' (its growth interval): {e}") from None


def nonneg(text: str) -> float:
    """A finite float >= 0."""
    v = number(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return v


def fraction(text: str) -> float:
    """A float in (0, 1]."""
    v = number(text)
    if not 0.0 < v <= 1.0:
        raise argparse.ArgumentTypeError(f"must lie in (0, 1], got {text!r}")
    return v


def int_at_least(low: int):
    """An integer type >= ``low``."""
    return int_between(low, None)


def int_between(low: int, high: int | None):
    """An integer type in [``low``, ``high``] (``high`` None: no upper bound)."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if high is None and v < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {text!r}")
        if high is not None and not low <= v <= high:
            raise argparse.ArgumentTypeError(f"must lie in [{low}, {high}], got {text!r}")
        return v

    parse.__name__ = f"int>={low}" if high is None else f"int in [{low}, {high}]"
    return parse


def refuse_with_resume(options: tuple[tuple[str, object, object], ...], what: str) -> None:
    """Raise a SceneError naming every option (name, value, default) given with ``--resume``: a resumed run keeps
    its own settings (``what`` names the run, e.g. "the run")."""
    from aca_warp.common.errors import SceneError

    given = [name for name, value, default in options if value != default]
    if given:
        raise SceneError(f"--resume continues {what} with its own settings; drop {', '.join(given)}")


CHECKPOINT_HELP = (
    "keep the {what} state in the run file every S of simulated time, so that a stopped or killed run can be resumed "
    "(default: automatic, every 5 s of wall time or less often, costing at most 2%% of the run; 0: none; "
    "docs/faults.md)"
)


def add_checkpoint_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """``--checkpoint-interval S`` (simulated time [s]; 0: none) and ``--no-checkpoint`` (the same as 0), into
    ``args.checkpoint_interval`` (None: automatic checkpoints, :class:`aca_warp.common.checkpoint.CheckpointClock`);
    ``what`` names the state kept (e.g. "solver")."""
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--checkpoint-interval", type=nonneg, metavar="S", help=CHECKPOINT_HELP.format(what=what))
    g.add_argument(
        "--no-checkpoint",
        dest="checkpoint_interval",
        action="store_const",
        const=0.0,
        help="no checkpoints (--checkpoint-interval 0): a stopped or killed run resumes from its start",
    )
