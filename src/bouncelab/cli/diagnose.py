"""``bouncelab diagnose``: not implemented yet."""

from __future__ import annotations

from bouncelab.errors import BouncelabError


def add_parser(sub) -> None:
    p = sub.add_parser("diagnose", help="(not implemented yet)")
    p.add_argument("rest", nargs="*")
    p.set_defaults(handler=run)


def run(args) -> int:
    raise BouncelabError(None, "'diagnose' is not implemented yet")
