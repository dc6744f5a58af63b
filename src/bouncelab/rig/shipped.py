"""Regenerate the shipped data set: every ``config/rig/*.yaml`` -> ``raw/<name>/``.

    python -m bouncelab.rig.shipped            # all configs, from the repository root
    python -m bouncelab.rig.shipped --only drop_test

The run id is the config file's stem. Each run folder is replaced (only ``run.yaml``
and ``recording.*`` in it); the ground truth goes to ``config/rig/truth/<name>.parquet``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bouncelab.errors import BouncelabError
from bouncelab.rig import run_rig


def shipped_configs(config_dir: Path) -> list[Path]:
    """The rig configs of the shipped runs, sorted by name."""
    return sorted(config_dir.glob("*.yaml"))


def regenerate(config_dir: Path, raw_dir: Path, truth_dir: Path, only: list[str] | None = None):
    """Run the rig for each config; returns ``[(name, seconds, n_flights), ...]``."""
    done = []
    for cfg in shipped_configs(config_dir):
        if only and cfg.stem not in only:
            continue
        t0 = time.perf_counter()
        res = run_rig(cfg, raw_dir / cfg.stem, truth_dir / f"{cfg.stem}.parquet", force=True)
        done.append((cfg.stem, time.perf_counter() - t0, len(res.truth)))
    return done


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bouncelab.rig.shipped", description=__doc__)
    ap.add_argument("--config-dir", default="config/rig", type=Path)
    ap.add_argument("--raw-dir", default="raw", type=Path)
    ap.add_argument("--truth-dir", default="config/rig/truth", type=Path)
    ap.add_argument("--only", nargs="*", help="config names (stems) to regenerate")
    args = ap.parse_args(argv)
    try:
        for name, secs, n in regenerate(args.config_dir, args.raw_dir, args.truth_dir, args.only):
            print(f"{name}: {secs:.1f} s, {n} true flights")
    except BouncelabError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
