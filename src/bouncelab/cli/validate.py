"""``bouncelab validate RUN_DIR``: check a run folder against CONTRACTS.md section 1.

Prints what it found (run id, kind, recording, channels with their ranges in volts,
steps, Gamma range and gaps, drop height and release) and exits 0; on bad input
raises :class:`~bouncelab.errors.BouncelabError`, which the CLI prints as one
``error:`` line. Reads only; never writes under the run folder.
"""

from __future__ import annotations

import json


def add_parser(sub) -> None:
    p = sub.add_parser(
        "validate",
        help="check a run folder (run.yaml and recording) and report what it holds",
        description="Check a run folder against the run format and report what it holds.",
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="the run folder, raw/<run_id>/")
    p.add_argument("--json", action="store_true", help="print the report as JSON instead of text")
    p.set_defaults(handler=run)


def run(args) -> int:
    from bouncelab.runs import validate_run  # imported late: keeps `bouncelab --help` fast

    report = validate_run(args.run_dir)
    if args.json:
        print(json.dumps(report.to_dict(), indent=2))
    else:
        print(report.summary())
    return 0
