"""``bouncelab extract RUN_DIR -o OUT``: the flight table of a run (CONTRACTS.md section 3).

The QC table per step is written beside it as ``<OUT stem>.qc<suffix>``.
"""

from __future__ import annotations

from pathlib import Path

from bouncelab.errors import BouncelabError
from bouncelab.tables import TABLE_SUFFIXES, write_table


def add_parser(sub) -> None:
    p = sub.add_parser(
        "extract",
        help="flight table of a run (and a QC table per step beside it)",
        description="Detect flights in a run's continuity channel; write OUT (.parquet or "
        ".csv) and the QC table <OUT stem>.qc<suffix>.",
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="run folder (holds run.yaml)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="flight table file")
    p.set_defaults(handler=run)


def _check_output(run_dir: Path, out: Path) -> None:
    """OUT must be a table file and must not lie inside the run folder we read."""
    if out.suffix.lower() not in TABLE_SUFFIXES:
        raise BouncelabError(out, "output must end in .parquet or .csv")
    try:
        out.resolve().relative_to(run_dir.resolve())
    except ValueError:
        return
    raise BouncelabError(out, "refusing to write inside the run folder that is read")


def run(args) -> int:
    from bouncelab.flights import extract_run, qc_path_for

    run_dir, out = Path(args.run_dir), Path(args.output)
    _check_output(run_dir, out)
    flights, qc = extract_run(run_dir)
    write_table(flights, out)
    write_table(qc, qc_path_for(out))
    n_set = int(flights["settled"].sum()) if len(flights) else 0
    print(f"{out}: {len(flights)} flights ({n_set} settled) in {len(qc)} steps")
    return 0
