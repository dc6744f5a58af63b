"""Can the repeat rule speak on a run without a random force?

The diagnosis names a run unexplained when the data's median repeat over the steps where
the final model's flights repeat is at least ``data_tol`` (``gap.diagnose.repeat_check``,
``repeat_reason``; docs/diagnosis.md section 1). This measures that median on every
generated case (the blind cases of ``config/blind/cases.yaml``, the independent and the
compliant generators' cases of ``bench_independent.py``) twice: with the case's **true**
library model simulated under its protocol (what a perfect fit would give), and with
the **final model its record holds** (``blind_validation.json``, ``independent.json``,
``compliant.json``). Each is the diagnosis's own ``_features`` (the model's best member
against the data), so nothing but the model differs from a diagnosis.

Reports, per source, the largest ``data_median / data_tol`` over the cases without an
effect outside the library (must stay below 1: a false alarm otherwise) and the least
over those with plate vibration (must reach 1: a miss otherwise), and which cases the
rule names. Reads the truth, so it is a benchmark of the rule, never part of it.

Run: ``python benchmarks/bench_repeat_rule.py --work DIR`` (each case's run folder and
its repeats are kept under ``DIR`` and reused; about 25 minutes from empty on 2 cores).
Writes ``benchmarks/results/repeat_rule.json``.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_independent import GENERATORS  # noqa: E402
from bench_truth_vs_fit import independent_true_params  # noqa: E402

from bouncelab.flights import extract_run  # noqa: E402
from bouncelab.gap.diagnose import (  # noqa: E402
    REPEAT_MIN_STEPS,
    _features,
    repeat_check,
    repeat_reason,
    shifted_repeats,
)
from bouncelab.gap.fit import FitSettings, make_problem, resolution_T  # noqa: E402
from bouncelab.gap.select import model_name  # noqa: E402
from bouncelab.physics.model import Model  # noqa: E402
from bouncelab.runs import load_run  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
OUT = RESULTS / "repeat_rule.json"


def model_of(effects: dict, ride_load: float | None = None) -> Model:
    """A model from ``effect -> params`` (the truth's or a record's, merged)."""
    params: dict = {}
    for ps in effects.values():
        params.update(ps)
    if "feedback" in effects and ride_load is not None:
        params.setdefault("ride_load", ride_load)
    return Model.parse(model_name(effects), params)


def repeats(run_dir: Path, model: Model) -> dict:
    """Per-step repeats (rad) of the data and of ``model`` under the run's protocol, as
    the diagnosis reads them, and one sample of the recording (rad)."""
    run = load_run(run_dir)
    table, qc = extract_run(run_dir)
    fs = FitSettings()
    problem = make_problem(
        run, table, float(qc["t_end_s"].max()), seed=0, n_members=fs.n_members,
        heldout_every=fs.heldout_every,
    )  # fmt: skip
    ps = _features(problem, model)["per_step"]
    return {
        "sample_rad": resolution_T(run, samples=1.0),
        "repeat_data": ps["repeat_data"].tolist(),
        "repeat_sim": ps["repeat_sim"].tolist(),
        "repeat_sim_shifted": shifted_repeats(problem, model).tolist(),
    }


def check_of(rec: dict) -> dict:
    """The rule's :func:`repeat_check` of kept per-step repeats, with the median's ratio
    to its limit and whether the rule names the run."""
    per_step = pd.DataFrame({k: rec[k] for k in ("repeat_data", "repeat_sim")}, dtype=float)
    c = repeat_check({"per_step": per_step}, rec["sample_rad"], shifted=rec["repeat_sim_shifted"])
    ratio = c["data_median"] / c["data_tol"] if c["data_median"] is not None else None
    return c | {"ratio": ratio, "named": repeat_reason(c) is not None}


def cached(path: Path, run_dir: Path, model: Model) -> dict:
    """:func:`repeats` of ``model`` on ``run_dir``, kept in ``path`` and read from it."""
    if path.is_file():
        return json.loads(path.read_text())
    rec = repeats(run_dir, model)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(rec))
    return rec


def blind_cases(work: Path):
    """Each blind case: (name, run folder, true library effects, outside effects, the
    record's (selected, fitted parameters) or None)."""
    from bouncelab.gap.blind import load_cases, make_case, true_effects
    from bouncelab.rig import read_truth

    record = json.loads((RESULTS / "blind_validation.json").read_text())["cases"]
    for case in load_cases(ROOT / "config" / "blind" / "cases.yaml"):
        run_dir, truth = make_case(case, work / "blind")
        lib, outside = true_effects(read_truth(truth)[1])
        rec = record.get(case["name"])
        yield case["name"], run_dir, lib, outside, rec and (rec["selected"], rec["fitted_params"])


def generator_cases(work: Path, generator: str):
    """Each case of ``bench_independent.py``'s ``generator``, as :func:`blind_cases`."""
    cases, make, stem = GENERATORS[generator]
    record = json.loads((RESULTS / f"{stem}.json").read_text())["cases"]
    for name, opts in cases.items():
        run_dir = work / generator / name
        if not (run_dir / "run.yaml").is_file():
            make(run_dir, **opts)
        truth = json.loads(run_dir.with_name(name + ".truth.json").read_text())
        lib = truth["effects"]
        if generator == "independent":
            lib = independent_true_params(lib)
        rec = record.get(name)
        yield name, run_dir, lib, truth.get("outside", []), rec and (rec["selected"], rec["fitted"])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--work", required=True, help="folder for the runs and per-case repeats")
    args = p.parse_args()
    logging.disable(logging.WARNING)  # the extraction's notes on vibration runs
    work = Path(args.work)
    # the rig's armature carries the riding body, the independent generator's is kicked
    # by impacts only, the compliant one's is pushed by the contact force
    sources = {
        "blind": (blind_cases(work), 1.0),
        "independent": (generator_cases(work, "independent"), 0.0),
        "compliant": (generator_cases(work, "compliant"), 1.0),
    }
    out: dict = {"what": __doc__.split("\n\n")[0], "sources": {}}
    for source, (cases, ride) in sources.items():
        rows = {}
        for name, run_dir, lib, outside, fitted in cases:
            row = {"outside": outside}
            true = model_of(lib, ride)
            rec = cached(work / "repeats" / f"{source}__{name}__true.json", run_dir, true)
            row["true"] = check_of(rec)
            if fitted is not None:  # the record's final model: its effects, its parameters
                selected, params = fitted
                final = model_of(
                    {e: {} for e in selected} | ({selected[0]: params} if selected else {})
                )
                rec = cached(work / "repeats" / f"{source}__{name}__fit.json", run_dir, final)
                row["fit"] = check_of(rec)
            rows[name] = row
            named = {k: (row[k]["ratio"], row[k]["named"]) for k in ("true", "fit") if k in row}
            print(source, name, named, flush=True)
        vib = {n: r for n, r in rows.items() if "random_vibration" in r["outside"]}
        clean = {n: r for n, r in rows.items() if not r["outside"]}

        def extreme(group, key, fn):
            vals = [
                (r[key]["ratio"], n)
                for n, r in group.items()
                if key in r
                and r[key]["ratio"] is not None
                and r[key]["model_robust"] >= REPEAT_MIN_STEPS
            ]
            return fn(vals) if vals else None

        out["sources"][source] = {
            "cases": len(rows),
            "without_outside_max_ratio": {k: extreme(clean, k, max) for k in ("true", "fit")},
            "vibration_min_ratio": {k: extreme(vib, k, min) for k in ("true", "fit")},
            "named": {
                k: sorted(n for n, r in rows.items() if k in r and r[k]["named"])
                for k in ("true", "fit")
            },
            "per_case": rows,
        }
        summary = {k: v for k, v in out["sources"][source].items() if k != "per_case"}
        print(source, json.dumps(summary), flush=True)
    OUT.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
