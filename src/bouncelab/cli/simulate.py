"""``bouncelab simulate``: the event-driven model on a Gamma grid (CONTRACTS.md sections 2, 5).

``bouncelab simulate --model M [--set NAME=VALUE ...] --gamma START:STOP:N [--flights N]
[--skip N] [--starts N] [--seed N] -o OUT`` writes one row per recorded flight
(Parquet or CSV by the extension of OUT) with the columns of
:data:`bouncelab.physics.FLIGHT_COLUMNS`.
"""

from __future__ import annotations

import sys

import numpy as np

from bouncelab.errors import BouncelabError

#: above this many flights a progress bar is shown (on a terminal only)
_PROGRESS_FLIGHTS = 20_000_000


def add_parser(sub) -> None:
    p = sub.add_parser(
        "simulate",
        help="run a model on a Gamma grid and write its flight table",
        description="Event-driven model of the bouncing body on a Gamma grid (nondimensional).",
    )
    p.add_argument(
        "--model", required=True, help="effects joined by '+', e.g. friction+restitution"
    )
    p.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="model parameter, repeatable (mu, e, k, a, psi, mass_ratio, f_ratio, zeta, s)",
    )
    p.add_argument("--gamma", required=True, metavar="START:STOP:N", help="Gamma grid, N points")
    p.add_argument(
        "--flights", type=int, default=200, help="flights recorded per Gamma (default 200)"
    )
    p.add_argument(
        "--skip", type=int, default=100, help="transient flights dropped first (default 100)"
    )
    p.add_argument("--starts", type=int, default=1, help="ensemble of start phases per Gamma")
    p.add_argument("--seed", type=int, default=0, help="seed of the ensemble's start phases")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="OUT.parquet or OUT.csv")
    p.set_defaults(handler=run)


def parse_grid(text: str) -> np.ndarray:
    """``"START:STOP:N"`` -> ``N`` evenly spaced Gamma values (inclusive), shape ``(N,)``."""
    parts = str(text).split(":")
    if len(parts) != 3:
        raise BouncelabError(None, f"--gamma {text!r} is not START:STOP:N")
    try:
        start, stop = float(parts[0]), float(parts[1])
        n = int(parts[2])
    except ValueError:
        raise BouncelabError(None, f"--gamma {text!r} is not START:STOP:N with numbers") from None
    if not (np.isfinite(start) and np.isfinite(stop)) or start < 0 or stop < start:
        raise BouncelabError(None, f"--gamma {text!r}: need 0 <= START <= STOP")
    if n < 1 or (n == 1 and start != stop):
        raise BouncelabError(None, f"--gamma {text!r}: N must be >= 1 (1 only if START == STOP)")
    return np.linspace(start, stop, n)


def run(args) -> int:
    from bouncelab.physics import Model, parse_assignments, simulate_grid
    from bouncelab.tables import TABLE_SUFFIXES, write_table

    out = str(args.output)
    if not out.lower().endswith(TABLE_SUFFIXES):
        raise BouncelabError(out, "output must end in .parquet or .csv")
    model = Model.parse(args.model, parse_assignments(args.sets))
    gammas = parse_grid(args.gamma)
    if args.flights < 1 or args.skip < 0 or args.starts < 1:
        raise BouncelabError(None, "--flights and --starts must be >= 1, --skip >= 0")
    total = gammas.size * args.starts * (args.flights + args.skip)
    chunks = [gammas]
    show = total > _PROGRESS_FLIGHTS and sys.stderr.isatty()
    if show:
        chunks = np.array_split(gammas, max(2, int(total // (_PROGRESS_FLIGHTS // 4))))
    frames = []
    it = chunks
    if show:
        from tqdm import tqdm

        it = tqdm(chunks, desc="simulate", unit="chunk", file=sys.stderr)
    for chunk in it:
        frames.append(
            simulate_grid(
                model, chunk, args.flights, n_skip=args.skip, n_starts=args.starts, seed=args.seed
            )
        )
    import pandas as pd

    df = frames[0] if len(frames) == 1 else pd.concat(frames, ignore_index=True)
    write_table(df, out)
    print(f"{len(df)} flights of model {model.name} at {gammas.size} Gamma values -> {out}")
    return 0
