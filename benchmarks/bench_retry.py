"""What the retry of an unexplained diagnosis (``bouncelab diagnose --retries 1``, the
default) would have said on the blind validation's multi-seed records: how many verdicts
it turns right, and how many right ones (out-of-library runs flagged unexplained) it
turns wrong.

Replays the records of ``bench_blind_seeds.py``, each case diagnosed with several
diagnosis seeds on the same recordings, so that a retry of seed ``s`` is the recorded
diagnosis at seed ``s + 1``. Every seed ``s`` whose ``s + 1`` is recorded starts a
diagnosis; where it is unexplained, :func:`bouncelab.gap.seeds.retry_index` picks between
the two. No diagnosis is run: the records hold each seed's selected set and verdict.

Records (in ``benchmarks/results``): ``blind_seeds_fresh_main.json`` (the five
combinations with an armature or a harmonic at fresh seeds 5-14), ``blind_seeds.json``
(the seven combinations at seeds 0-4, the seeds earlier changes were chosen on),
``blind_seeds_singles.json`` (the 28 single-effect cases at seeds 0-4) and
``blind_seeds_ool.json`` (the 10 out-of-library cases at seeds 0-1, session 42).

Prints and writes ``benchmarks/results/retry_replay.json``.

    python benchmarks/bench_retry.py
"""

from __future__ import annotations

import json
from pathlib import Path

from bouncelab.gap.seeds import retry_index

RESULTS = Path(__file__).resolve().parent / "results"
RECORDS = (
    "blind_seeds_fresh_main.json",
    "blind_seeds.json",
    "blind_seeds_singles.json",
    "blind_seeds_ool.json",
)


def replay(record: dict) -> dict:
    """Counts over every case and first seed ``s`` with ``s + 1`` recorded: ``runs``;
    verdicts and sets right without the retry (``first_*``) and with it
    (``reported_*``); ``retried`` (first seed unexplained) and ``retry_reported`` (the
    second explains the run); and each change of verdict, by case and first seed."""
    counts = dict.fromkeys(
        ("runs", "first_verdicts", "reported_verdicts", "first_sets", "reported_sets",
         "retried", "retry_reported"),
        0,
    )  # fmt: skip
    changed = []
    for name, case in sorted(record["cases"].items()):
        rows = {int(s): r for s, r in case["seeds"].items()}
        for s in sorted(rows):
            if s + 1 not in rows:
                continue
            tried = [rows[s]] if not rows[s]["unexplained"] else [rows[s], rows[s + 1]]
            shown = tried[retry_index(tried)]
            counts["runs"] += 1
            counts["first_verdicts"] += bool(rows[s]["verdict_right"])
            counts["reported_verdicts"] += bool(shown["verdict_right"])
            counts["first_sets"] += bool(rows[s]["set_right"])
            counts["reported_sets"] += bool(shown["set_right"])
            counts["retried"] += len(tried) > 1
            counts["retry_reported"] += shown is not rows[s]
            if shown["verdict_right"] != rows[s]["verdict_right"]:
                changed.append(
                    {"case": name, "first_seed": s, "now_right": bool(shown["verdict_right"])}
                )
    return {**counts, "changed": changed}


def main() -> None:
    out = {}
    for name in RECORDS:
        path = RESULTS / name
        if not path.is_file():
            print(f"{name}: not recorded, skipped")
            continue
        r = out[name] = replay(json.loads(path.read_text()))
        lost = sum(not c["now_right"] for c in r["changed"])
        print(
            f"{name}: {r['runs']} diagnoses, {r['retried']} unexplained and retried, "
            f"{r['retry_reported']} retries reported; verdicts right {r['first_verdicts']} "
            f"-> {r['reported_verdicts']} ({lost} right ones lost), sets right "
            f"{r['first_sets']} -> {r['reported_sets']}"
        )
    path = RESULTS / "retry_replay.json"
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
