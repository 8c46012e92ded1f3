"""The ``dragline`` command.

Every subcommand lives in its own module ``pipelines/_cmd_<name>.py`` with
``add_parser(subparsers)`` and ``run(args) -> int``. Exit codes (docs/interfaces.md):
0 success, 2 bad input or usage (one line on stderr, no traceback),
1 internal failure.
"""

from __future__ import annotations

import argparse
import importlib
import sys

COMMANDS = ("run", "simulate", "synth", "calibrate", "reconstruct", "compare", "diagnose", "replay", "inspect", "rig",
            "bench")


class UsageError(ValueError):
    """Bad input or usage: reported in one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        sub = self.prog.split(" ", 1)[1] if " " in self.prog else ""
        raise UsageError(f"{sub}: {message}" if sub else message)


def build_parser():
    parser = _Parser(
        prog="dragline",
        description="Check a dynamic model of a rope-rigged machine against motion capture.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    handlers = {}
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"dragline.pipelines._cmd_{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"dragline.pipelines._cmd_{name}":
                raise
            continue
        module.add_parser(sub)
        handlers[name] = module.run
    return parser, handlers


def main(argv=None):
    """Entry point; returns the exit code."""
    from ._signals import handle_termination

    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        with handle_termination():
            parser, handlers = build_parser()
            args = parser.parse_args(argv)
            if args.command is None:
                parser.print_help()
                return 0
            return int(handlers[args.command](args) or 0)
    except (UsageError, ValueError, FileNotFoundError, IsADirectoryError, PermissionError) as exc:
        print(f"dragline: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`, which stopped reading
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt as exc:
        return _stopped(exc)
    except Exception as exc:  # noqa: BLE001 - the last line of defence
        from dragline.simulate import SimulationError

        interrupt = _interruption(exc)
        if interrupt is not None:
            return _stopped(interrupt)
        from dragline.compare import ExecutorError

        if isinstance(exc, (SimulationError, ExecutorError)):  # a failure of the run, not of this program
            print(f"dragline: {_one_line(exc)}", file=sys.stderr)
            return 1
        import traceback

        traceback.print_exc()
        print(f"dragline: internal error: {_one_line(exc)}", file=sys.stderr)
        return 1


def _interruption(exc):
    """The KeyboardInterrupt (a signal) that ``exc`` was raised while handling, if any.

    A signal that arrives inside compiled code (numba's dispatcher) comes out
    as a SystemError whose context is the interrupt.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _stopped(interrupt):
    from ._signals import Terminated

    if isinstance(interrupt, Terminated):
        print(f"dragline: stopped by {interrupt}; workers stopped, no partial outputs were left under final names",
              file=sys.stderr)
        return interrupt.exit_code
    print("dragline: interrupted; no partial outputs were left under final names", file=sys.stderr)
    return 130


def _one_line(exc):
    text = str(exc) if str(exc) else type(exc).__name__
    if isinstance(exc, OSError) and exc.filename and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}"
    return " ".join(text.split())


if __name__ == "__main__":
    sys.exit(main())
