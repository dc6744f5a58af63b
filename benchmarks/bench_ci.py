"""Benchmark of CI: `.ci/run` on a fresh clone of a commit, timed, with the slowest tests.

Goal: CI under 20 minutes on 2 cores, on any hour (this machine's speed swings about 2x
between hours; `machine_speed` before and after says which hour it was). CI runs
`.ci/run` on a fresh clone of main: an editable install of the clone, then the README's
`pytest`. This does the same in a scratch clone, with ``--durations`` added to see where
the time goes, then points the editable install back at this checkout.

Prints and writes benchmarks/results/ci.json (``--out`` to write elsewhere).

    python benchmarks/bench_ci.py [--rev HEAD]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_physics import machine_speed  # noqa: E402

GOAL_S = 20 * 60
DURATION_RE = re.compile(r"^([\d.]+)s (setup|call|teardown)\s+(\S+)$", re.M)
SUMMARY_RE = re.compile(r"^=* ?(\d+ passed.*?) in ([\d.]+)s", re.M)


def slowest(output: str, n: int = 10) -> list[dict]:
    """The ``n`` slowest phases pytest's ``--durations`` printed: seconds, phase, test id."""
    rows = [
        {"s": float(s), "phase": phase, "test": test}
        for s, phase, test in DURATION_RE.findall(output)
    ]
    return sorted(rows, key=lambda r: -r["s"])[:n]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", default="HEAD", help="commit to clone and test (default HEAD)")
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results" / "ci.json")
    args = ap.parse_args(argv)
    rev = subprocess.run(
        ["git", "rev-parse", args.rev], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.strip()

    speed_before = machine_speed()
    with tempfile.TemporaryDirectory(prefix="bouncelab-ci-") as tmp:
        clone = Path(tmp) / "clone"
        subprocess.run(["git", "clone", "-q", str(REPO), str(clone)], check=True)
        subprocess.run(["git", "checkout", "-q", rev], cwd=clone, check=True)
        # .ci/run's own two steps, the test command with --durations added
        env = dict(os.environ)
        t0 = time.perf_counter()
        install = subprocess.run(
            [sys.executable, "-m", "pip", "install", "-q", "-e", ".[test]"],
            cwd=clone, capture_output=True, text=True, env=env, check=False,
        )  # fmt: skip
        t_install = time.perf_counter() - t0
        try:
            if install.returncode != 0:
                sys.exit(f"pip install in the clone failed:\n{install.stderr[-3000:]}")
            print(f"installed the clone of {rev[:7]} in {t_install:.0f} s; running pytest ...")
            t1 = time.perf_counter()
            tests = subprocess.run(
                [sys.executable, "-m", "pytest", "-q", "--durations=15", "-p", "no:cacheprovider"],
                cwd=clone, capture_output=True, text=True, env=env, check=False,
            )  # fmt: skip
            t_tests = time.perf_counter() - t1
        finally:
            # the editable install points at this checkout again
            subprocess.run(
                [sys.executable, "-m", "pip", "install", "-q", "-e", str(REPO), "--no-deps"],
                capture_output=True, check=False,
            )  # fmt: skip
    output = tests.stdout + tests.stderr
    summary = SUMMARY_RE.findall(output)
    total = t_install + t_tests
    record = {
        "rev": rev,
        "pytest_returncode": tests.returncode,
        "pytest_summary": summary[-1][0] if summary else output[-500:],
        "install_s": round(t_install, 1),
        "tests_s": round(t_tests, 1),
        "total_s": round(total, 1),
        "goal_s": GOAL_S,
        "meets_goal": tests.returncode == 0 and total <= GOAL_S,
        "slowest": slowest(output),
        "cpu_count": os.cpu_count(),
        "machine_feedback_mflights_s": {"before": speed_before, "after": machine_speed()},
    }
    print(json.dumps(record, indent=1))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=1) + "\n")
    return 0 if record["meets_goal"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
