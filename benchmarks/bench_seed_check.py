"""What ``bouncelab diagnose --check-seeds 3`` would have said on the blind validation's
five-seed records: is the conclusion it reports (that of most seeds) right more often
than one seed's, does it flag the wrong ones, and how often does it flag right ones?

Replays the records of ``bench_blind_seeds.py`` (``blind_seeds.json``: the seven
combinations; ``blind_seeds_singles.json``: the 28 single-effect cases), each diagnosed
with diagnosis seeds 0-4 on the same recordings. Every seed ``s`` in turn starts a check
of seeds ``s``, ``s+1`` and ``s+2`` (modulo 5) with the library's own
:func:`bouncelab.gap.seeds.majority_index` and :func:`bouncelab.gap.seeds.seed_check`.
No diagnosis is run: the records hold each seed's selected set and verdict, which is all
the check compares, but no final gap: where the three seeds all differ (3 of the 35
combination checks, none of the single effects), the replay reports the first seed,
where ``diagnose`` reports the one of least final held-out gap.

Prints and writes ``benchmarks/results/seed_check_replay.json``.

    python benchmarks/bench_seed_check.py
"""

from __future__ import annotations

import json
from pathlib import Path

from bouncelab.gap.seeds import majority_index, seed_check

RESULTS = Path(__file__).resolve().parent / "results"
RECORDS = ("blind_seeds.json", "blind_seeds_singles.json")
N_CHECKED = 3


def as_diagnosis(seed: int, row: dict) -> dict:
    """The keys of a diagnosis that :func:`seed_check` reads, from one seed's record (the
    records keep no final gap or parameters: the gaps are set equal, so conclusions
    shared equally go to the first seed)."""
    return {
        "design": {"seed": seed},
        "selected": row["selected"],
        "unexplained": row["unexplained"],
        "final_rel_gap": 0.0,
        "final_model": {"params": {}},
    }


def _right(row: dict) -> bool:
    return bool(row["set_right"] and row["verdict_right"])


def replay(record: dict, n_checked: int = N_CHECKED) -> dict:
    """Counts over every case and first seed of a check: the first seed's conclusion
    right (``first_right``, what a diagnosis without the check reports) and the reported
    one's (``reported_right``); reported draws wrong or right, flagged or quiet; and the
    flagged checks by case and first seed."""
    counts = {"checks": 0, "first_right": 0, "reported_right": 0}
    counts |= {"wrong_flagged": 0, "wrong_quiet": 0, "right_flagged": 0, "right_quiet": 0}
    flagged = []
    for name, case in sorted(record["cases"].items()):
        seeds = sorted(int(s) for s in case["seeds"])
        for i, s in enumerate(seeds):
            checked = [seeds[(i + j) % len(seeds)] for j in range(n_checked)]
            rows = [case["seeds"][str(t)] for t in checked]
            diagnoses = [as_diagnosis(t, r) for t, r in zip(checked, rows, strict=True)]
            reported = majority_index(diagnoses)
            check = seed_check(diagnoses, reported)
            right = _right(rows[reported])
            counts["checks"] += 1
            counts["first_right"] += _right(rows[0])
            counts["reported_right"] += right
            key = ("right_" if right else "wrong_") + ("quiet" if check["agree"] else "flagged")
            counts[key] += 1
            if not check["agree"]:
                flagged.append({"case": name, "first_seed": s, "reported_right": right})
    return {**counts, "flagged": flagged}


def main() -> None:
    out = {"n_checked_seeds": N_CHECKED}
    for name in RECORDS:
        out[name] = replay(json.loads((RESULTS / name).read_text()))
        r = out[name]
        print(
            f"{name}: {r['checks']} checks; right: one seed {r['first_right']}, the "
            f"reported (most seeds') {r['reported_right']}; reported wrong and flagged "
            f"{r['wrong_flagged']} of {r['wrong_flagged'] + r['wrong_quiet']}; reported "
            f"right and flagged {r['right_flagged']} of "
            f"{r['right_flagged'] + r['right_quiet']}"
        )
    path = RESULTS / "seed_check_replay.json"
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
