"""``bouncelab diagnose RUN_DIR [--calibration CAL.json] -o OUT.json``: the gap diagnosis.

Writes the JSON of CONTRACTS.md section 6 (more keys: docs/diagnosis.md). The run folder
is only read; the output must lie outside it.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from bouncelab.errors import BouncelabError


def add_parser(sub) -> None:
    p = sub.add_parser(
        "diagnose",
        help="sim-to-real gap diagnosis of a sweep run (which effects, how far, where)",
        description=(
            "Refit each candidate effect (friction, restitution, harmonic, feedback, "
            "gamma_scale) added to the baseline model, select effects forward on held-out "
            "Gamma steps, and write the diagnosis JSON (CONTRACTS.md section 6)."
        ),
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="sweep run folder (CONTRACTS.md section 1)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.json", help="output JSON file")
    p.add_argument(
        "--calibration", metavar="CAL.json", help="drop-test calibration (CONTRACTS.md section 4)"
    )
    p.add_argument(
        "--fix-calibration",
        action="store_true",
        help="hold mu and e at the calibration's values instead of fitting them",
    )
    p.add_argument(
        "--fix-accel",
        action="store_true",
        help="hold what the run's accelerometer reads: gamma_scale's s; the feedback's "
        "f_ratio and zeta where it reads the armature's ring-down; the harmonic's k, a, psi "
        "where it reads one (needs an accel channel and accel_v_per_g)",
    )
    p.add_argument(
        "--flights",
        metavar="FLIGHTS",
        help="the run's flight table (.parquet/.csv from `bouncelab extract`); "
        "default: extract it from the recording",
    )
    p.add_argument("--baseline", default="ideal", help="model the effects are added to")
    p.add_argument("--seed", type=int, default=0, help="seed of simulations and optimisers")
    p.add_argument(
        "--workers",
        type=int,
        default=2,
        help="processes that evaluate the fits' populations (default 2)",
    )
    p.add_argument(
        "--check-seeds",
        type=int,
        default=1,
        metavar="N",
        help="diagnose with N seeds (SEED, SEED+1, ...), report the conclusion most of them "
        "reached and warn when they disagree; N times the time (default 1: no check)",
    )
    p.add_argument(
        "--retries",
        type=int,
        default=None,
        metavar="N",
        help="when the diagnosis leaves the gap unexplained, diagnose again with the next "
        "seed, up to N times, and report the first that explains the run (default 1; 0: "
        "never; not with --check-seeds)",
    )
    p.add_argument(
        "--repeat-limit",
        type=float,
        default=None,
        metavar="RAD",
        help="name the run unexplained (a random force) when its flights, in the median "
        "over the steps where the final model's flights repeat, repeat by this much or more "
        "(radians of drive phase, or 2.5 samples where that is more; default 0.02; a rig "
        "whose flights scatter for a cause it accepts can raise it)",
    )
    p.add_argument(
        "--timings",
        action="store_true",
        help="add wall-clock timings (not deterministic): the whole command, each seed's "
        "diagnosis, the fits by stage",
    )
    p.set_defaults(handler=run)


def run(args) -> int:
    from bouncelab.errors import collected_warnings
    from bouncelab.gap.diagnose import diagnose_run
    from bouncelab.gap.seeds import RETRIES, retry_warning, seed_warning
    from bouncelab.gap.select import SelectSettings
    from bouncelab.physics import Model

    out = Path(args.output)
    if out.suffix.lower() != ".json":
        raise BouncelabError(out, "output must end in .json")
    run_dir = Path(args.run_dir)
    if out.resolve().is_relative_to(run_dir.resolve()):
        raise BouncelabError(out, "output must not be written under the run folder it reads")
    if args.workers < 1:
        raise BouncelabError(None, f"--workers must be >= 1, not {args.workers}")
    if args.check_seeds < 1:
        raise BouncelabError(None, f"--check-seeds must be >= 1, not {args.check_seeds}")
    if args.retries is not None and args.retries < 0:
        raise BouncelabError(None, f"--retries must be >= 0, not {args.retries}")
    if args.repeat_limit is not None and not args.repeat_limit > 0:
        raise BouncelabError(None, f"--repeat-limit must be > 0 rad, not {args.repeat_limit}")
    if args.fix_calibration and not args.calibration:
        raise BouncelabError(None, "--fix-calibration needs --calibration CAL.json")
    Model.parse(args.baseline)  # a bad model name is bad input: one error line
    # the extraction's warnings are printed as they are logged: not again at the end
    with collected_warnings() as printed:
        result = diagnose_run(
            run_dir,
            calibration=args.calibration,
            baseline=args.baseline,
            seed=args.seed,
            flights=args.flights,
            fix_calibration=args.fix_calibration,
            workers=args.workers,
            include_timings=args.timings,
            check_seeds=args.check_seeds,
            retries=RETRIES if args.retries is None else args.retries,
            fix_accel=args.fix_accel,
            select_settings=(
                None
                if args.repeat_limit is None
                else SelectSettings(repeat_limit=args.repeat_limit)
            ),
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1, sort_keys=False, allow_nan=False) + "\n")
    for warning in result.get("input_warnings", []):
        if warning not in printed:
            print(f"warning: {warning}", file=sys.stderr)
    disagreement = seed_warning(result["seed_check"]) if "seed_check" in result else None
    if disagreement:
        print(f"warning: {disagreement}", file=sys.stderr)
    retried = retry_warning(result["retry"]) if "retry" in result else None
    if retried:
        print(f"warning: {retried}", file=sys.stderr)
    print(summary_line(out, result), file=sys.stderr)
    if "timings" in result:
        print(timings_line(result["timings"]), file=sys.stderr)
    return 0


def timings_line(timings: dict) -> str:
    """The line ``--timings`` adds: the whole time, each seed's diagnosis, and the
    reported diagnosis's stages (seconds, wall clock)."""
    runs = ", ".join(f"seed {d['seed']} {d['total_s']:.0f} s" for d in timings["diagnoses"])
    stages = ", ".join(f"{k} {v['seconds']:.0f} s" for k, v in timings["stages"].items())
    return (
        f"time: {timings['total_s']:.0f} s (reading {timings['read_s']:.0f} s; {runs}); "
        f"fits of the reported diagnosis: {stages}"
    )


def summary_line(out: Path, result: dict) -> str:
    """The one line the command prints: what was selected, the gap before and after, the
    verdict, and its margin when the verdict is borderline (``verdict_margin``)."""
    from bouncelab.gap.seeds import borderline_retries

    sel = ", ".join(result["selected"]) or "nothing"
    verdict = "unexplained" if result["unexplained"] else "explained"
    margin = result.get("verdict_margin") or {}
    if margin.get("borderline"):
        verdict += (
            f" (borderline: {margin['rel_gap']:.3g} +- {margin['se']:.2g} noise floors "
            f"against the limit {margin['limit']:g})"
        )
    check = result.get("seed_check")
    if check is not None:
        n = len(check["seeds"])
        k = check["reported_share"][0]
        verdict += (
            f"; {n} seeds agree"
            if check["agree"]
            else f"; {n} seeds disagree, seed {check['reported_seed']}'s reported ({k} of {n})"
        )
    retry = result.get("retry")
    if retry is not None:
        first = retry["seeds"][0]
        if retry["reported_seed"] != first:
            verdict += f" by seed {retry['reported_seed']} (seed {first} left it unexplained)"
        elif border := borderline_retries(retry):
            seeds = ", ".join(str(r["seed"]) for r in border)
            verdict += (
                f"; retried with {len(retry['seeds']) - 1} more seed(s), explained only on a "
                f"borderline verdict (seed {seeds}), not reported"
            )
        else:
            verdict += f"; retried with {len(retry['seeds']) - 1} more seed(s), none explains it"
    return (
        f"wrote {out}: selected {sel}; gap {result['baseline']['gap']:.4g} -> "
        f"{result['final_gap']:.4g} rad (noise floor {result['noise_floor']:.4g}), {verdict}"
    )
