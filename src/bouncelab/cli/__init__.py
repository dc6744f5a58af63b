"""The ``bouncelab`` command: one subcommand per module in this package.

Each module defines ``add_parser(subparsers)`` and a ``run(args) -> int`` handler.
Bad input raises :class:`bouncelab.errors.BouncelabError`; :func:`main` turns it
into one ``error: <file>: <problem>`` line on stderr and exit status 2, with no
traceback unless ``--debug`` is given (CONTRACTS.md section 2).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback

from bouncelab import __version__
from bouncelab.errors import BouncelabError

SUBCOMMANDS = ("validate", "extract", "calibrate", "simulate", "diagnose", "rig")


class _Parser(argparse.ArgumentParser):
    """argparse with its usage errors as one ``error:`` line too (a missing ``-o``, an
    unknown option): argparse's own two lines (usage, then ``prog: error: ...``) do not
    start with ``error:`` as CONTRACTS.md section 2 asks. The subcommands' parsers are of
    this class as well (``add_subparsers`` takes the parent's class)."""

    def error(self, message: str):
        self.exit(2, f"error: {self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="bouncelab",
        description="Bouncing ball on a vibrating plate: runs, flights, models, gap diagnosis.",
    )
    parser.add_argument("--version", action="version", version=f"bouncelab {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        importlib.import_module(f"bouncelab.cli.{name}").add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except BouncelabError as exc:
        if args.debug:
            traceback.print_exc()
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # the reader of our output went away (`| head`): not an error of ours
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # an internal fault, not bad input: still one line
        if args.debug:
            traceback.print_exc()
        print(
            f"error: internal error ({type(exc).__name__}: {exc}); "
            "rerun with --debug for a traceback",
            file=sys.stderr,
        )
        return 1


if __name__ == "__main__":
    sys.exit(main())
