"""``bouncelab validate``: not implemented yet."""

from __future__ import annotations

from bouncelab.errors import BouncelabError


def add_parser(sub) -> None:
    p = sub.add_parser("validate", help="(not implemented yet)")
    p.add_argument("rest", nargs="*")
    p.set_defaults(handler=run)


def run(args) -> int:
    raise BouncelabError(None, "'validate' is not implemented yet")
