"""Benchmark of the workflow: a full run over the shipped data, a no-op rerun, a dropped-in run.

Goals (issue 5): `snakemake --cores 2` over the shipped data in at most 3 minutes after
installation (numba caches warm, as after the first run of the tests or the pipeline);
a no-op rerun in at most 5 s; a dropped-in sweep re-runs only its own jobs and the report.

Runs in a scratch copy of the project (raw/ is copied, never written). Prints and
writes benchmarks/results/pipeline.json.

    python benchmarks/bench_pipeline.py
"""

from __future__ import annotations

import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_physics import machine_speed  # noqa: E402

PARTS = ("Snakefile", "workflow", "config", "report", "profiles", "raw")


def copy_project(dest: Path) -> None:
    for part in PARTS:
        src = REPO / part
        if src.is_dir():
            shutil.copytree(src, dest / part, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(src, dest / part)


def timed_snakemake(work: Path, *args: str) -> tuple[float, str]:
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", "--cores", "2", *args],
        cwd=work,
        capture_output=True,
        text=True,
        check=False,
    )
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"snakemake {' '.join(args)} failed:\n{proc.stderr[-3000:]}")
    return dt, proc.stdout + proc.stderr


def finished_jobs(output: str) -> int:
    """Number of jobs a snakemake run finished (checkpoints add jobs after the first plan)."""
    return len(re.findall(r"^Finished jobid: ", output, re.M))


def slowest_jobs(output: str, n: int = 8) -> dict[str, float]:
    """Wall seconds (1 s resolution) of the ``n`` slowest jobs of a snakemake run, from the
    time stamps of its output (job start: the stamp before ``rule NAME:``; end: the stamp
    before ``Finished jobid: N``). Keys: ``rule`` or ``rule[wildcards]``."""
    from datetime import datetime

    stamp, rule, job = None, None, None
    started, names, times = {}, {}, {}
    for line in output.splitlines():
        if m := re.match(r"^\[(\w{3} \w{3} +\d+ [\d:]+ \d{4})\]$", line):
            stamp = datetime.strptime(m.group(1), "%a %b %d %H:%M:%S %Y")
        elif m := re.match(r"^(?:local)?rule (\w+):$", line):
            rule, job = m.group(1), None
        elif (m := re.match(r"^    jobid: (\d+)$", line)) and rule is not None:
            job = m.group(1)
            names[job], started[job] = rule, stamp
        elif (m := re.match(r"^    wildcards: (.*)$", line)) and job is not None:
            names[job] = f"{rule}[{m.group(1)}]"
        elif (m := re.match(r"^Finished jobid: (\d+)", line)) and m.group(1) in started:
            times[names[m.group(1)]] = (stamp - started[m.group(1)]).total_seconds()
            rule = job = None
    top = sorted(times.items(), key=lambda kv: -kv[1])[:n]
    return dict(top)


def main() -> None:
    # the machine's speed before and after (bench_physics.machine_speed): a virtual
    # machine's can swing by a quarter within the hour, and the full run's time with it
    speed_before = machine_speed()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp) / "project"
        work.mkdir()
        copy_project(work)
        full_s, out = timed_snakemake(work)
        full_jobs = finished_jobs(out)
        slowest = slowest_jobs(out)
        noop_s, out = timed_snakemake(work)
        assert "Nothing to be done" in out, out[-2000:]
        shutil.copytree(work / "raw" / "accel_g2-4", work / "raw" / "dropped_in")
        drop_s, out = timed_snakemake(work)
        wild = re.findall(r"^    wildcards: (.*)$", out, re.M)
        others = [w for w in wild if "run=dropped_in" not in w]
    result = {
        "full_run_s": round(full_s, 1),
        "full_run_jobs": full_jobs,
        "full_run_slowest_jobs_s": slowest,
        "noop_rerun_s": round(noop_s, 2),
        "dropped_in_run_s": round(drop_s, 1),
        "dropped_in_foreign_jobs": others,
        "goals": {"full_run_s": 180, "noop_rerun_s": 5},
        "meets_goals": full_s <= 180 and noop_s <= 5 and not others,
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "load_average_1min": round(os.getloadavg()[0], 2),
        "machine_feedback_mflights_s": {"before": speed_before, "after": machine_speed()},
    }
    print(json.dumps(result, indent=1))
    out_path = REPO / "benchmarks" / "results" / "pipeline.json"
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
