"""Whether a diagnosis depends on its own seed: the same run diagnosed with other seeds.

Why: on runs with several effects the selection is partly a lottery of the optimisers'
draws and of the orbits the simulations settle on (docs/diagnosis.md section 5, "Answers
that depend on the diagnosis's own seed"): over five diagnosis seeds the blind
combinations came out right in 30 of 35 verdicts, and the independent
``friction_restitution_harmonic`` is right at seeds 0 and 2 and wrong at seed 1. A user
sees one draw. ``bouncelab diagnose --check-seeds N`` runs the whole diagnosis with ``N``
seeds (``N`` times the time) and :func:`seed_check` states whether they agree.
"""

from __future__ import annotations


def _summary(result: dict) -> dict:
    """What one diagnosis (the dict of :func:`bouncelab.gap.diagnose.diagnose_run`)
    concluded: its seed, selected effects, verdict, final gap in noise floors and the
    final model's parameters."""
    final = result.get("final_model") or {}
    return {
        "seed": int(result["design"]["seed"]),
        "selected": list(result["selected"]),
        "unexplained": bool(result["unexplained"]),
        "final_rel_gap": float(result["final_rel_gap"]),
        "params": {k: float(v) for k, v in (final.get("params") or {}).items()},
    }


def seed_check(results: list[dict]) -> dict:
    """How the diagnoses of one run under different seeds agree.

    Parameters
    ----------
    results : diagnoses of the same run and settings, the reported one first (at least
        one).

    Returns
    -------
    dict, JSON-ready:
        ``seeds`` : the seeds, in the order of ``results``;
        ``diagnoses`` : per seed, ``seed``, ``selected``, ``unexplained``,
        ``final_rel_gap`` (noise floors) and ``params`` (the final model's);
        ``sets_agree`` : every seed selected the same effects (in any order);
        ``verdicts_agree`` : every seed gave the same verdict (explained or not);
        ``agree`` : both;
        ``params_range`` : ``{name: [min, max]}`` over the seeds of each parameter every
        final model has: how far the lottery moves it (the seeds' spread, not a
        confidence interval).
    """
    if not results:
        raise ValueError("seed_check needs at least one diagnosis")
    rows = [_summary(r) for r in results]
    sets_agree = len({frozenset(r["selected"]) for r in rows}) == 1
    verdicts_agree = len({r["unexplained"] for r in rows}) == 1
    shared = set.intersection(*(set(r["params"]) for r in rows))
    params_range = {
        name: [min(r["params"][name] for r in rows), max(r["params"][name] for r in rows)]
        for name in sorted(shared)
    }
    return {
        "seeds": [r["seed"] for r in rows],
        "diagnoses": rows,
        "sets_agree": sets_agree,
        "verdicts_agree": verdicts_agree,
        "agree": sets_agree and verdicts_agree,
        "params_range": params_range,
    }


def _conclusion(row: dict) -> str:
    chosen = " + ".join(row["selected"]) or "nothing"
    verdict = "unexplained" if row["unexplained"] else "explained"
    return f"seed {row['seed']}: {chosen}, {verdict}"


def seed_warning(check: dict) -> str | None:
    """One line when the seeds of :func:`seed_check` disagree, naming what each
    concluded; None when they agree."""
    if check["agree"]:
        return None
    return (
        "the diagnosis depends on its seed ("
        + "; ".join(_conclusion(r) for r in check["diagnoses"])
        + "): read its selection as one draw of several"
    )
