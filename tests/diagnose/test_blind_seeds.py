"""The benchmark of the blind verdicts over diagnosis seeds
(``benchmarks/bench_blind_seeds.py``): what counts as a right verdict, and the counts."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from bench_blind_seeds import seeds_record, verdict_right  # noqa: E402


def score(selected, true, unexplained=False, kind="combination", errors=None):
    return {
        "kind": kind,
        "selected": selected,
        "true": true,
        "set_right": sorted(selected) == sorted(true),
        "unexplained": unexplained,
        "param_errors": errors or {},
    }


def test_a_right_verdict_is_the_right_set_explained_or_an_outside_case_flagged():
    assert verdict_right(score(["friction"], ["friction"]))
    assert not verdict_right(score(["friction"], ["friction"], unexplained=True))
    assert not verdict_right(score(["feedback"], ["friction"]))
    assert verdict_right(score(["harmonic"], [], unexplained=True, kind="outside"))
    assert not verdict_right(score([], [], kind="outside"))


def test_the_record_counts_per_case_and_leaves_reused_times_out():
    """Two seeds of one case: right with mu 5 % off, then the set wrong with its one
    fitted parameter 20 % off (counted as a run beyond 15 %); seed 1 was reused."""
    right = score(["friction", "restitution"], ["friction", "restitution"],
                  errors={"friction": {"mu": 0.05}, "restitution": {"e": 0.01}})  # fmt: skip
    wrong = score(["restitution"], ["friction", "restitution"], errors={"restitution": {"e": 0.2}})
    per_seed = {
        0: {"cases": {"fr": right}, "timings": {"fr": {"diagnose_s": 12.0}}},
        1: {"cases": {"fr": wrong}, "timings": {"fr": {"diagnose_s": 0.01}}},
    }
    rec = seeds_record(per_seed, reused={1: {"fr"}})
    case = rec["cases"]["fr"]
    assert (case["set_right"], case["verdict_right"], case["params_within_15pc"]) == (1, 1, 1)
    assert case["seeds"]["0"]["max_param_error"] == 0.05
    assert case["seeds"]["0"]["diagnose_s"] == 12.0 and case["seeds"]["1"]["diagnose_s"] is None
    assert rec["summary"] == {
        "seeds": [0, 1], "case_runs": 2, "set_right": 1, "verdict_right": 1,
        "params_within_15pc": 1, "verdict_right_first": 1, "retried": 0, "rescued": 0,
    }  # fmt: skip


def test_the_record_counts_what_the_retry_turned():
    """Three seeds of one combination: seed 0 right at once; seed 1 unexplained, its
    retry right (rescued); seed 2 retried to no avail. And an out-of-library case
    retried: flagged by its first diagnosis already, so nothing rescued."""
    right = score(["friction", "feedback"], ["friction", "feedback"])
    lost = score(["feedback"], ["friction", "feedback"], unexplained=True)
    outside = score(["harmonic"], [], unexplained=True, kind="outside")
    again = [{"seed": 1, "selected": ["feedback"], "unexplained": True, "final_rel_gap": 3.2},
             {"seed": 2, "selected": ["friction", "feedback"], "unexplained": False,
              "final_rel_gap": 1.1}]  # fmt: skip
    per_seed = {
        0: {"cases": {"sl": right, "vib": outside}},
        1: {"cases": {"sl": right, "vib": outside}},
        2: {"cases": {"sl": lost, "vib": outside}},
    }
    retries = {1: {"sl": again, "vib": again[:1]}, 2: {"sl": again[:1] * 2}}
    rec = seeds_record(per_seed, retries=retries)
    sl, vib = rec["cases"]["sl"], rec["cases"]["vib"]
    assert [sl["seeds"][s]["verdict_right_first"] for s in "012"] == [True, False, False]
    assert (sl["verdict_right"], sl["verdict_right_first"], sl["retried"], sl["rescued"]) == (
        2, 1, 2, 1,
    )  # fmt: skip
    assert (vib["verdict_right_first"], vib["retried"], vib["rescued"]) == (3, 1, 0)
    assert sl["seeds"]["1"]["retry"] == again
    summary = rec["summary"]
    assert (summary["retried"], summary["rescued"], summary["verdict_right_first"]) == (3, 1, 4)
