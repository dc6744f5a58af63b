"""``bouncelab rig CONFIG.yaml -o RUN_DIR [--truth TRUTH.parquet]``: the virtual rig."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser(
        "rig",
        help="virtual rig: simulate the lab from a config and write a run folder",
        description=(
            "Simulate the lab (compliant contact, friction, shaker feedback, sensor chain) "
            "from a rig config and write a run folder (CONTRACTS.md section 1); the ground "
            "truth goes to a separate Parquet file. See docs/rig.md."
        ),
    )
    p.add_argument("config", help="rig config YAML (keys: docs/rig.md)")
    p.add_argument(
        "-o", "--output", required=True, help="run folder to write (its name is the run id)"
    )
    p.add_argument("--truth", help="ground truth Parquet file, outside the run folder")
    p.add_argument("--force", action="store_true", help="replace an earlier rig output in RUN_DIR")
    p.set_defaults(handler=run)


def run(args) -> int:
    from bouncelab.rig import run_rig

    result = run_rig(args.config, args.output, args.truth, force=args.force)
    print(
        f"wrote {args.output}: {result.n_samples / result.fs:.2f} s, "
        f"{len(result.roles)} channel(s) ({', '.join(result.roles)}), "
        f"{len(result.truth)} true flights"
    )
    return 0
