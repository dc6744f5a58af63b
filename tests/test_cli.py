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


def test_usage_errors_are_one_error_line():
    """A missing -o, an unknown subcommand or option: exit 2 and one line starting with
    'error:' (argparse's own message was two lines, the first 'usage: ...')."""
    for args in (("extract", "raw/sweep_g0-4"), ("frob",), ("validate", "x", "--bogus")):
        out = run_cli(*args)
        lines = out.stderr.strip().splitlines()
        assert out.returncode == 2, args
        assert len(lines) == 1 and lines[0].startswith("error:"), (args, out.stderr)
    assert "-o/--output" in run_cli("extract", "raw/sweep_g0-4").stderr
