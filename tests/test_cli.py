"""The command line's error contract: one ``error:`` line, non-zero exit, no traceback."""

import subprocess
import sys


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "bouncelab", *args], capture_output=True, text=True, check=False
    )


def test_help_lists_every_subcommand():
    out = run_cli("--help")
    assert out.returncode == 0
    for name in ("validate", "extract", "calibrate", "simulate", "diagnose", "rig"):
        assert name in out.stdout
