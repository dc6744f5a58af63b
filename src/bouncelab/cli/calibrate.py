"""``bouncelab calibrate RUN_DIR -o OUT.json``: friction and restitution of a drop run."""

from __future__ import annotations

import json
from pathlib import Path

from bouncelab.errors import BouncelabError


def add_parser(sub) -> None:
    p = sub.add_parser(
        "calibrate",
        help="friction and restitution from a drop run (JSON)",
        description="Fit Coulomb friction mu and restitution e to a drop run's fall time and "
        "bounce flights; 95 % bootstrap intervals (CONTRACTS.md section 4).",
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="drop run folder (holds run.yaml)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.json", help="output JSON")
    p.add_argument("--n-boot", type=int, default=2000, help="bootstrap refits (default 2000)")
    p.add_argument("--seed", type=int, default=0, help="bootstrap seed (default 0)")
    p.set_defaults(handler=run)


def run(args) -> int:
    from bouncelab.calibration import calibrate_run

    run_dir, out = Path(args.run_dir), Path(args.output)
    if out.suffix.lower() != ".json":
        raise BouncelabError(out, "output must end in .json")
    try:
        out.resolve().relative_to(run_dir.resolve())
        raise BouncelabError(out, "refusing to write inside the run folder that is read")
    except ValueError:
        pass
    if args.n_boot < 1:
        raise BouncelabError(None, f"--n-boot must be at least 1, not {args.n_boot}")
    cal = calibrate_run(run_dir, n_boot=args.n_boot, seed=args.seed)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(cal, indent=2) + "\n")
    print(
        f"{out}: mu = {cal['mu']:.4f} [{cal['mu_ci'][0]:.4f}, {cal['mu_ci'][1]:.4f}], "
        f"e = {cal['restitution']:.4f} [{cal['restitution_ci'][0]:.4f}, "
        f"{cal['restitution_ci'][1]:.4f}], {cal['n_bounces']} bounces"
    )
    return 0
