"""Raw run folders: ``run.yaml`` parsing and validation, recording readers, ``validate``.

CONTRACTS.md section 1 fixes the format; docs/runs.md is the user's guide.

>>> from bouncelab.runs import load_run, read_recording, step_table
>>> run = load_run("raw/sweep_0_4")                     # doctest: +SKIP
>>> rec = read_recording(run, roles=("continuity",))   # doctest: +SKIP
>>> steps = step_table(run, rec.duration_s)            # doctest: +SKIP
"""

from bouncelab.runs.readers import Recording, read_recording
from bouncelab.runs.spec import ROLES, RUN_ID_PATTERN, Run, discover_runs, load_run, run_schema
from bouncelab.runs.validate import ValidationReport, gamma_gaps, step_table, validate_run

__all__ = [
    "ROLES",
    "RUN_ID_PATTERN",
    "Recording",
    "Run",
    "ValidationReport",
    "discover_runs",
    "gamma_gaps",
    "load_run",
    "read_recording",
    "run_schema",
    "step_table",
    "validate_run",
]
