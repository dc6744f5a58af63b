"""What the Snakemake scripts call: each function is one job's work, testable alone.

The scripts under ``workflow/scripts/`` only unpack the ``snakemake`` object, call one
function here, and write its result. Keeping the logic here means the tests exercise it
without Snakemake, and a user can run any stage from Python.
"""

from __future__ import annotations

import json
from pathlib import Path

from bouncelab.errors import BouncelabError


def check_run_verdict(run_dir) -> dict:
    """Validate a run folder and return a JSON-ready verdict; never raises for bad input.

    Returns ``{"ok": bool, "run": id, "error": one line or "", "summary": text,
    "info": validate's dict or {}}``. The workflow records this instead of failing, so
    that one broken run cannot stop the report; the run's own jobs still fail with
    the same error.
    """
    from bouncelab.runs import validate_run

    run_dir = Path(run_dir)
    try:
        report = validate_run(run_dir)
    except BouncelabError as exc:
        return {"ok": False, "run": run_dir.name, "error": str(exc), "summary": "", "info": {}}
    return {
        "ok": True,
        "run": run_dir.name,
        "error": "",
        "summary": report.summary(),
        "info": json.loads(json.dumps(report.to_dict(), default=str)),
    }
