"""Command line ``aca-warp COMMAND ...``: the top-level parser and the entry point.

Each command registers its own parser from its package (``add_parsers(sub)`` in aca_warp.hf.commands,
aca_warp.lf.commands, aca_warp.analysis.commands, aca_warp.sweep.commands, aca_warp.bench) and sets ``handler``; nothing
imports this module. Parsing imports no simulation code, so ``--help`` and argument errors answer at once.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from aca_warp import __version__
from aca_warp.common import interrupts
from aca_warp.common.errors import AcaError, command_line, nearest


class Parser(argparse.ArgumentParser):
    """argparse's parser that reads a negative number in any notation (``-1e-4``, ``-.5``, ``-3``) as a value, not as
    an option: ``--duration -1e-4`` then meets the option's own check ("must be positive") like ``--duration=-1e-4``,
    instead of "expected one argument". No ``aca-warp`` option looks like a negative number. The command's
    subparsers are of this class too (argparse gives them the class of their parent)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message: str) -> NoReturn:
        """A mistyped command line: one line on stderr, naming where the options are listed, and exit code 2 (not
        argparse's usage block before it)."""
        self.exit(2, f"{self.prog}: error: {message}; see {self.prog} --help\n")

    def parse_args(self, args: Sequence[str] | None = None, namespace: Any = None) -> Any:  # type: ignore[override]
        """argparse's, but an unknown option is refused by the command it was given to (``aca-warp hf: error: …;
        see aca-warp hf --help``), with the nearest option of that command where one is close ("did you mean
        --duration?")."""
        ns, extras = self.parse_known_args(args, namespace)
        if extras:
            command = self._command_parser(ns)
            own = {s for action in self._actions for s in action.option_strings}
            early = [x for x in extras if x.split("=")[0] in own and command is not self]
            if early:  # an option of aca-warp itself, given after the command
                self.error(f"{early[0]} is an option of {self.prog} itself: give it before the command")
            options = {s.lstrip("-"): s for action in command._actions for s in action.option_strings}
            typed = [x.split("=")[0].lstrip("-") for x in extras if x.startswith("-")][:3]
            near = [nearest(x, options) for x in typed]
            hint = "".join(f" (did you mean {options[m]}?)" for m in near if m is not None)
            command.error(f"unrecognized arguments: {' '.join(extras)}{hint}")
        return ns

    def _command_parser(self, ns: Any) -> argparse.ArgumentParser:
        """The parser of the command ``ns`` holds (its subcommand's), or this one."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                return action.choices.get(getattr(ns, action.dest, None), self)
        return self


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``aca-warp``."""
    from aca_warp.analysis.commands import add_parsers as add_analysis
    from aca_warp.bench import add_parsers as add_bench
    from aca_warp.hf.commands import add_parsers as add_hf
    from aca_warp.hf.commands import run_epilog
    from aca_warp.lf.commands import add_parsers as add_lf
    from aca_warp.sweep.commands import add_parsers as add_sweep

    p = Parser(
        prog="aca-warp",
        description="Abstract Cellular Automaton of the brake pad-disc "
        "boundary layer (Merlis & Ostermeyer 2019) in NVIDIA Warp.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=run_epilog("hf/lf --resume", lf=True),
    )
    p.add_argument("--version", action="version", version=f"aca-warp {__version__}")
    p.add_argument(
        "--verbose", action="store_true", help="show Warp's own messages (start-up, module loads, CUDA driver)"
    )
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (add_hf, add_lf, add_analysis, add_sweep, add_bench):
        add(sub)
    return p


def run(argv: Sequence[str] | None = None) -> NoReturn:
    """Entry point of the ``aca-warp`` console script: :func:`main`, then the end of the process
    (:func:`~aca_warp.common.interrupts.exit_process`): a SIGINT or SIGTERM that comes after the command's work, while
    the process cleans up (or one the work never saw), ends it with 130 or 143 and one line, never half-way through
    the clean-up."""
    code = main(argv, hold=True)

    def late(signum: int, code: int) -> str:
        name = "SIGTERM" if signum == signal.SIGTERM else "Ctrl-C"
        return (
            f"aca-warp: interrupted ({name}), but the command's work was not stopped: it ended with exit code {code} "
            "and its output is as the command left it"
        )

    interrupts.exit_process(code, late)


def main(argv: Sequence[str] | None = None, *, hold: bool = False) -> int:
    """Run one ``aca-warp`` command in this process; returns its exit code (``hold``: the process ends next, see
    :func:`run`).

    Every error is one ``aca-warp: error:`` line and the error's exit code; SIGINT (Ctrl-C) and SIGTERM end a
    command with one ``aca-warp: interrupted`` line saying what its output holds, exit 130 and 143
    (:mod:`aca_warp.common.interrupts`)."""
    with interrupts.installed(hold=hold), command_line():  # from the start: a signal during start-up ends the same way
        args: argparse.Namespace | None = None
        try:
            args = build_parser().parse_args(argv)
            if args.verbose:
                os.environ["ACA_WARP_VERBOSE"] = "1"
            if getattr(args, "uses_warp", True):  # analyze and plot read files only: no Warp to start
                from aca_warp.common.devices import init_warp

                init_warp()
            _check_output_folder(args)
            code = args.handler(args)
            # the result is final: a signal from here on, or one the work never saw, is recorded (run() reports it)
            interrupts.finished(unseen=code not in (130, 143))
        except AcaError as e:
            interrupts.finished()
            print(f"aca-warp: error: {e}", file=sys.stderr)
            return e.exit_code  # 2 bad input, 3 unphysical, 4 output not writable (docs/faults.md)
        except KeyboardInterrupt as e:
            code = interrupts.exit_code(e)
            left = "nothing was written" if args is None else _left(args)
            print(f"aca-warp: interrupted ({'SIGTERM' if code == 143 else 'Ctrl-C'}); {left}", file=sys.stderr)
            return code
        if code == 130 and interrupts.received() is not None:  # a command that handled the interrupt itself
            return interrupts.exit_code()
        return code


def _check_output_folder(args: argparse.Namespace) -> None:
    """The output folder of ``sweep -o DIR`` must be creatable and writable before the sweep expands its spec (the
    other commands check their outputs themselves): a file there, or a path under one, is refused before the spec's
    expansion is printed. A folder that holds a sweep's manifest is left to the sweep: a finished sweep there is
    complete even where the folder takes no new file (:func:`~aca_warp.sweep.run_sweep`)."""
    if args.command != "sweep":
        return
    from aca_warp.common.files import check_output_folder
    from aca_warp.sweep.manifest import MANIFEST

    if not (Path(args.output) / MANIFEST).is_file():
        check_output_folder(args.output)


def _left(args: argparse.Namespace) -> str:
    """What an interrupted command left behind, in words (docs/faults.md "Interrupts")."""
    cmd = args.command
    if cmd in ("hf", "lf", "rerun"):
        out = args.resume if getattr(args, "resume", None) else args.output
        if out is None:
            return "nothing was written"
        return _run_file_state(Path(out))
    if cmd == "analyze":
        return f"{args.run} is unchanged (an earlier /analysis, if any, is kept)"
    if cmd == "plot":
        from aca_warp.analysis.commands import plot_leftovers

        return plot_leftovers(args.output_dir, bool(args.only))
    if cmd == "sweep":
        return f"finished shards are kept in {args.output}; the same command continues the sweep"
    return "nothing was written"


def _run_file_state(path: Path) -> str:
    """'RUN.h5 keeps …' for an interrupted run: where its samples end and how to continue it."""
    from aca_warp.common.files import is_complete, partial_path, recovery

    final = path.with_name(path.name.removesuffix(".partial"))
    part = partial_path(final)
    if part.exists() and final.exists() and is_complete(final):  # a run kept beside the file it replaces
        kept = f"{final}, the earlier file it was to replace, is unchanged"
        return f"{part} keeps the interrupted run and {kept}: {recovery(final)}"
    if part.exists():  # interrupted before the file was closed (or a killed run's file)
        return f"{part} was left as it was: {recovery(final)}"
    if not final.exists():
        return "nothing was written"
    try:
        import h5py

        with h5py.File(final, "r") as f:
            if bool(f.attrs.get("complete", False)):
                return f"{final} is complete"
            t = f["global/time"]
            held = f"keeps the samples to t = {float(t[-1]):.6g} s" if t.shape[0] else "holds no sample yet"
    except (OSError, KeyError, ValueError, RuntimeError):
        return f"{final} was written but cannot be read back"
    return f"{final} {held}, marked incomplete; {recovery(final)}"


if __name__ == "__main__":
    run()
