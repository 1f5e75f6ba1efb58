"""The ``magsoro`` command line. Each sub-command lives in its own module under ``magsoro.commands`` and
exposes ``register(subparsers)``, which adds its parser and sets ``func`` (called with the parsed args, returns
an exit code). Add a new command by writing such a module and naming it in ``COMMANDS``."""

import argparse
import importlib
import sys

from magsoro._version import __version__
from magsoro.errors import MagsoroError, Terminated

COMMANDS = [
    "magsoro.commands.run",
    "magsoro.commands.docs",
    "magsoro.commands.bench",
    "magsoro.commands.characterization",
    "magsoro.commands.rod",
    "magsoro.commands.epm_pose",
    "magsoro.commands.evert",
    "magsoro.commands.sense",
    "magsoro.commands.plan",
    "magsoro.commands.materials",
    "magsoro.commands.show",
    "magsoro.commands.sweep",
    "magsoro.commands.converge",
    "magsoro.commands.report",
    "magsoro.commands.render",
    "magsoro.commands.live",
    "magsoro.commands.validate",
    "magsoro.commands.optimize",
    "magsoro.commands.reproduce",
    "magsoro.commands.doctor",
    "magsoro.commands.import_magneticmpm",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="magsoro", description="Simulator for magnetic soft robots.")
    # own dest names: a sub-command's option of the same name cannot then shadow them
    parser.add_argument("--version", dest="print_version", action="store_true", help="print the version and exit (with --verbose: also "
                        "Python, every dependency and whether Warp sees CUDA)")
    parser.add_argument("--verbose", dest="version_verbose", action="store_true", help="with --version: the versions of the dependencies")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(name).register(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.print_version:
        from magsoro._version import verbose_version

        print(verbose_version() if args.version_verbose else f"magsoro {__version__}")
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    _stop_on_sigterm()
    try:
        return int(args.func(args) or 0)
    except MagsoroError as exc:
        print(f"magsoro {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file the command itself opened: one line naming it, not a traceback
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"magsoro {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except UnicodeDecodeError as exc:
        print(f"magsoro {args.command}: error: a file is not UTF-8 text ({exc.reason} at byte {exc.start})", file=sys.stderr)
        return 2
    except Terminated as exc:  # a command without its own clean-up: still one line, the signal's exit status
        print(f"magsoro {args.command}: {exc}", file=sys.stderr)
        return 128 + exc.signum


def _stop_on_sigterm() -> None:
    """SIGTERM raises :class:`Terminated` (a KeyboardInterrupt) in the main thread, so a run stopped by
    ``timeout``, Slurm or ``docker stop`` ends like one stopped with Ctrl-C: final state, results and run.json
    status 'interrupted' written, instead of a run.json left saying 'running'."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return

    def handler(signum, frame):
        raise Terminated(signum)

    signal.signal(signal.SIGTERM, handler)


if __name__ == "__main__":
    sys.exit(main())
