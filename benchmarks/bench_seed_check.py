"""What ``bouncelab diagnose --check-seeds 3`` would have said on the blind validation's
five-seed records: does it flag the reported draws that are wrong, and how often does it
flag right ones?

Replays the records of ``bench_blind_seeds.py`` (``blind_seeds.json``: the seven
combinations; ``blind_seeds_singles.json``: the 28 single-effect cases), each diagnosed
with diagnosis seeds 0-4 on the same recordings. Every seed ``s`` is taken in turn as the
reported one and checked against seeds ``s+1`` and ``s+2`` (modulo 5) with the library's
own :func:`bouncelab.gap.seeds.seed_check`. No diagnosis is run: the records hold each
seed's selected set and verdict, which is all the check compares.

Prints and writes ``benchmarks/results/seed_check_replay.json``.

    python benchmarks/bench_seed_check.py
"""

from __future__ import annotations

import json
from pathlib import Path

from bouncelab.gap.seeds import seed_check

RESULTS = Path(__file__).resolve().parent / "results"
RECORDS = ("blind_seeds.json", "blind_seeds_singles.json")
N_CHECKED = 3


def as_diagnosis(seed: int, row: dict) -> dict:
    """The keys of a diagnosis that :func:`seed_check` reads, from one seed's record (the
    records keep no final gap or parameters: they are not compared)."""
    return {
        "design": {"seed": seed},
        "selected": row["selected"],
        "unexplained": row["unexplained"],
        "final_rel_gap": 0.0,
        "final_model": {"params": {}},
    }


def replay(record: dict, n_checked: int = N_CHECKED) -> dict:
    """Counts over every case and reported seed: wrong draws flagged or not, right draws
    flagged or quiet; and the flagged cases by name."""
    counts = {"wrong_flagged": 0, "wrong_quiet": 0, "right_flagged": 0, "right_quiet": 0}
    flagged = []
    for name, case in sorted(record["cases"].items()):
        seeds = sorted(int(s) for s in case["seeds"])
        for i, s in enumerate(seeds):
            checked = [seeds[(i + j) % len(seeds)] for j in range(n_checked)]
            rows = [case["seeds"][str(t)] for t in checked]
            check = seed_check([as_diagnosis(t, r) for t, r in zip(checked, rows, strict=True)])
            right = rows[0]["set_right"] and rows[0]["verdict_right"]
            key = ("right_" if right else "wrong_") + ("quiet" if check["agree"] else "flagged")
            counts[key] += 1
            if not check["agree"]:
                flagged.append({"case": name, "seed": s, "reported_right": bool(right)})
    return {**counts, "flagged": flagged}


def main() -> None:
    out = {"n_checked_seeds": N_CHECKED}
    for name in RECORDS:
        out[name] = replay(json.loads((RESULTS / name).read_text()))
        r = out[name]
        print(
            f"{name}: wrong draws flagged {r['wrong_flagged']} of "
            f"{r['wrong_flagged'] + r['wrong_quiet']}; right draws flagged "
            f"{r['right_flagged']} of {r['right_flagged'] + r['right_quiet']}"
        )
    path = RESULTS / "seed_check_replay.json"
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
