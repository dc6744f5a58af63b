"""Validation of the gap diagnosis on withheld effects, with the virtual rig.

    python -m bouncelab.gap.blind --out results/blind [--cases config/blind/cases.yaml]
        [--only NAME ...] [--merge-into benchmarks/results/blind_validation.json]

For each case (a partial rig config, ``config/blind/cases.yaml``) the rig writes a run
folder and, elsewhere, its ground truth. :func:`bouncelab.gap.diagnose.diagnose_run` is
then run on the run folder alone; only afterwards does :func:`score_case` read the truth
file, derive the true effects and parameters from the rig's own parameters (not from the
case's name), and compare. :func:`summarize` gives the confusion matrix of true against
selected effects, the parameter recovery errors, the false-alarm rate on null cases and
whether the out-of-library cases come out unexplained.

Layout of ``--out``: ``configs/<case>.yaml``, ``runs/<case>/`` (what the diagnosis sees),
``truth/<case>.parquet`` (only the scoring reads it), ``diagnoses/<case>.json``,
``scores.json`` (per case and summary).
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from bouncelab.errors import BouncelabError
from bouncelab.gap.fit import warned_params
from bouncelab.physics import EFFECT_ORDER
from bouncelab.yamlfile import read_yaml

#: Default case file, relative to the repository root.
DEFAULT_CASES = Path("config/blind/cases.yaml")

#: Goals of the validation (issue 6): stated here, measured by :func:`summarize`.
GOALS = {"top_effect_right": 0.9, "param_rel_error": 0.15, "null_false_alarms": 0}

#: Labels of the confusion matrix: the library effects and "none".
LABELS = (*EFFECT_ORDER, "none")

#: Case sets: ``development`` cases were seen while the diagnosis was designed (not
#: independent evidence); ``validation`` cases were written after it was frozen.
CASE_SETS = ("validation", "development")


def deep_merge(base: dict, over: dict) -> dict:
    """``base`` with ``over`` merged in, recursively for mappings (lists are replaced)."""
    out = copy.deepcopy(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def load_cases(path: str | Path = DEFAULT_CASES) -> list[dict]:
    """Cases ``[{"name", "rig"}]`` with each ``rig`` merged over the file's ``base``."""
    path = Path(path)
    doc = read_yaml(path, "blind case file")
    if not isinstance(doc, dict) or not isinstance(doc.get("cases"), list):
        raise BouncelabError(path, "blind case file needs a 'cases' list")
    base = doc.get("base") or {}
    out = []
    for case in doc["cases"]:
        if not isinstance(case, dict) or "name" not in case:
            raise BouncelabError(path, f"case {case!r} needs a name")
        kind = str(case.get("set", "validation"))
        if kind not in CASE_SETS:
            raise BouncelabError(path, f"case {case['name']!r}: set must be one of {CASE_SETS}")
        out.append(
            {
                "name": str(case["name"]),
                "set": kind,
                "rig": deep_merge(base, case.get("rig") or {}),
            }
        )
    return out


def true_effects(params: dict) -> tuple[dict, list[str]]:
    """The library effects present in a rig truth, with their model parameters, and the
    effects outside the library.

    Parameters
    ----------
    params : the ``params`` of :func:`bouncelab.rig.read_truth` (``config``, ``derived``).

    Returns
    -------
    (library, outside): ``library`` maps effect -> {param: true value} (model units of
    CONTRACTS.md section 5: ``mass_ratio`` and ``f_ratio`` from the rig's derived numbers);
    ``outside`` lists out-of-library effects that are on.
    """
    cfg, der = params["config"], params["derived"]
    body, drive, shaker, eff = cfg["body"], cfg["drive"], cfg["shaker"], cfg["effects"]
    lib: dict[str, dict] = {}
    if body["friction_mu"] > 0:
        lib["friction"] = {"mu": float(body["friction_mu"])}
    if body["restitution"] > 0:
        lib["restitution"] = {"e": float(body["restitution"])}
    harmonics = [h for h in drive.get("harmonics", []) if h.get("a", 0) != 0]
    if harmonics:
        h = harmonics[0]
        lib["harmonic"] = {"k": float(h["k"]), "a": float(h["a"]), "psi": float(h.get("psi", 0))}
    if shaker["feedback"]:
        lib["feedback"] = {
            "mass_ratio": float(der["mass_ratio"]),
            "f_ratio": float(der["f_ratio"]),
            "zeta": float(shaker["damping_ratio"]),
        }
    if drive["gamma_scale"] != 1.0:
        lib["gamma_scale"] = {"s": float(drive["gamma_scale"])}
    outside = []
    if eff["random_vibration_rms_m"] > 0:
        outside.append("random_vibration")
    if eff["drag_n_s_per_m"] > 0:
        outside.append("drag")
    if eff["restitution_slope_s_per_m"] != 0:
        outside.append("velocity_dependent_restitution")
    if eff["sensor_delay_s"] > 0:
        outside.append("sensor_delay")
    return lib, outside


def relative_errors(true: dict, fitted: dict) -> dict:
    """``|fitted - true| / |true|`` per parameter the two share (psi: the wrapped phase
    difference over 2 pi; gamma_scale ``s``: relative error of ``s``)."""
    out = {}
    for name, t in true.items():
        if name not in fitted:
            continue
        f = float(fitted[name])
        if name == "psi":
            d = (f - t + np.pi) % (2 * np.pi) - np.pi
            out[name] = float(abs(d) / (2 * np.pi))
        elif t != 0:
            out[name] = float(abs(f - t) / abs(t))
    return out


def interval_hits(true: dict, ci: dict) -> dict:
    """``{name: bool}``: whether each true parameter lies in the diagnosis's interval
    (psi: on the circle). Parameters without an interval are left out."""
    out = {}
    for name, t in true.items():
        if name not in ci:
            continue
        lo, hi = (float(v) for v in ci[name])
        if name == "psi":
            half = (hi - lo) / 2.0
            mid = (hi + lo) / 2.0
            out[name] = bool(abs((t - mid + np.pi) % (2 * np.pi) - np.pi) <= half)
        else:
            out[name] = bool(lo <= t <= hi)
    return out


def score_case(diagnosis: dict, truth_params: dict) -> dict:
    """Compare a diagnosis with the truth of its case (read only here).

    Returns a dict: ``true`` (library effects), ``outside`` (out-of-library effects),
    ``kind`` (``null``, ``single``, ``combination``, ``outside``), ``selected``,
    ``top`` (first selected or "none"), ``top_right`` (single-effect cases: the top
    effect is the true one), ``set_right`` (the selected set equals the true set),
    ``unexplained``, ``false_alarm`` (null cases: anything selected or unexplained),
    ``flagged`` (outside cases: unexplained), ``param_errors`` (relative errors of the
    true effects' parameters that the final model fitted), ``param_in_interval``
    (whether each of them lies in the last accepted step's interval), ``param_warned``
    (whether the last accepted step warns about each of them: loose, on a bound or
    trading off, :func:`bouncelab.gap.fit.warned_params`).
    """
    lib, outside = true_effects(truth_params)
    selected = list(diagnosis["selected"])
    top = selected[0] if selected else "none"
    if outside:
        kind = "outside"
    elif not lib:
        kind = "null"
    elif len(lib) == 1:
        kind = "single"
    else:
        kind = "combination"
    fitted = diagnosis.get("final_model", {}).get("params", {})
    steps = diagnosis.get("steps") or []
    ci = steps[-1].get("params_ci", {}) if steps else {}
    warned = warned_params(steps[-1].get("warnings", [])) if steps else set()
    errors, hits, flags = {}, {}, {}
    for eff, params in lib.items():
        if eff in selected:
            errors[eff] = relative_errors(params, fitted)
            hits[eff] = interval_hits(params, ci)
            flags[eff] = {name: name in warned for name in errors[eff]}
    out = {
        "true": sorted(lib),
        "true_params": lib,
        "outside": outside,
        "kind": kind,
        "selected": selected,
        "top": top,
        "set_right": sorted(selected) == sorted(lib),
        "unexplained": bool(diagnosis["unexplained"]),
        "param_errors": errors,
        "param_in_interval": hits,
        "param_warned": flags,
        "fitted_params": fitted,
    }
    if kind == "single":
        out["top_right"] = top == next(iter(lib))
    if kind == "null":
        out["false_alarm"] = bool(selected) or bool(diagnosis["unexplained"])
    if kind == "outside":
        out["flagged"] = bool(diagnosis["unexplained"])
    return out


def warning_counts(pairs: list[tuple[bool, bool]]) -> dict:
    """Parameters counted by their warnings, from ``(within the goal, warned about)``
    per parameter: ``n_params``, ``n_outside_goal`` and of those
    ``n_outside_goal_warned``, ``n_unwarned`` and of those ``n_unwarned_within_goal``."""
    return {
        "n_params": len(pairs),
        "n_outside_goal": sum(not ok for ok, _ in pairs),
        "n_outside_goal_warned": sum(not ok and w for ok, w in pairs),
        "n_unwarned": sum(not w for _, w in pairs),
        "n_unwarned_within_goal": sum(ok and not w for ok, w in pairs),
    }


def summarize(scores: dict[str, dict]) -> dict:
    """Confusion matrix, recovery errors, false alarms, flagged out-of-library cases.

    The confusion matrix counts, for every case with one true library effect or none,
    the true label (rows) against the top selected effect (columns), over
    :data:`LABELS`. ``single_set_right`` counts the single-effect cases whose selected
    set is exactly the true effect (the matrix sees only the top one, not a spurious
    second effect). Combination cases are listed with their selected sets. Parameter
    errors are those of the null, single-effect and combination cases (per case they
    stay in ``scores[name]["param_errors"]``, out-of-library cases included).
    ``param_warnings`` counts the same parameters by the diagnosis's warnings: how many
    missed the goal and how many of those were warned about, how many had no warning
    and how many of those met the goal (whether a value given without a warning can be
    taken as it is).
    """
    idx = {lab: i for i, lab in enumerate(LABELS)}
    cm = np.zeros((len(LABELS), len(LABELS)), dtype=int)
    singles = nulls = outs = 0
    top_right = set_right = false_alarms = flagged = 0
    errs: dict[str, list[float]] = {}
    hits: list[bool] = []
    warned: list[tuple[bool, bool]] = []  # (within the goal, warned about) per parameter
    for sc in scores.values():
        if sc["kind"] in ("single", "null"):
            t = sc["true"][0] if sc["true"] else "none"
            cm[idx[t], idx[sc["top"]]] += 1
        if sc["kind"] == "single":
            singles += 1
            top_right += int(sc["top_right"])
            set_right += int(sc["set_right"])
        if sc["kind"] == "null":
            nulls += 1
            false_alarms += int(sc["false_alarm"])
        if sc["kind"] == "outside":
            outs += 1
            flagged += int(sc["flagged"])
        if sc["kind"] == "outside":
            continue  # an out-of-library truth (e varying with speed) has no one true value
        for eff, pe in sc["param_errors"].items():
            for name, v in pe.items():
                if eff == "harmonic" and name == "k":
                    continue  # a discrete choice: right or wrong, counted below
                errs.setdefault(f"{eff}.{name}", []).append(v)
                flag = sc.get("param_warned", {}).get(eff, {}).get(name)
                if flag is not None:
                    warned.append((v <= GOALS["param_rel_error"], bool(flag)))
        for eff, ph in sc.get("param_in_interval", {}).items():
            hits += [h for name, h in ph.items() if not (eff == "harmonic" and name == "k")]
    all_err = [v for vs in errs.values() for v in vs]
    within = float(np.mean(np.asarray(all_err) <= GOALS["param_rel_error"])) if all_err else None
    return {
        "labels": list(LABELS),
        "confusion": cm.tolist(),
        "n_single": singles,
        "top_effect_right": top_right / singles if singles else None,
        "single_set_right": set_right,
        "n_null": nulls,
        "null_false_alarms": false_alarms,
        "n_outside": outs,
        "outside_flagged": flagged,
        "param_errors": {k: sorted(v) for k, v in sorted(errs.items())},
        "param_within_goal": within,
        "n_params_in_interval": int(sum(hits)),
        "n_params_scored": len(hits),
        "param_warnings": warning_counts(warned),
        "combinations": {
            name: {"true": sc["true"], "selected": sc["selected"], "set_right": sc["set_right"]}
            for name, sc in scores.items()
            if sc["kind"] == "combination"
        },
        "goals": GOALS,
    }


def make_case(case: dict, out_dir: Path) -> tuple[Path, Path]:
    """Write the case's rig config and run the rig: ``(run folder, truth file)``."""
    from bouncelab.rig import run_rig

    name = case["name"]
    cfg_path = out_dir / "configs" / f"{name}.yaml"
    cfg_path.parent.mkdir(parents=True, exist_ok=True)
    cfg_path.write_text(yaml.safe_dump(case["rig"], sort_keys=True))
    run_dir = out_dir / "runs" / name
    truth = out_dir / "truth" / f"{name}.parquet"
    if not (run_dir / "run.yaml").is_file() or not truth.is_file():
        run_rig(cfg_path, run_dir, truth, force=True)
    return run_dir, truth


def run_blind(
    cases: list[dict],
    out_dir: str | Path,
    *,
    seed: int = 0,
    workers: int = 1,
    log=print,
) -> dict:
    """Make, diagnose and score every case; write ``scores.json``; return its content.

    The diagnosis of a case is made (and written) before its truth is read. Existing
    run folders and diagnoses under ``out_dir`` are reused (delete them to redo).
    """
    from bouncelab.gap.diagnose import diagnose_run
    from bouncelab.rig import read_truth

    out_dir = Path(out_dir)
    scores, timings = {}, {}
    for case in cases:
        name = case["name"]
        t0 = time.perf_counter()
        run_dir, truth_path = make_case(case, out_dir)
        t1 = time.perf_counter()
        diag_path = out_dir / "diagnoses" / f"{name}.json"
        if diag_path.is_file():
            diagnosis = json.loads(diag_path.read_text())
        else:
            diagnosis = diagnose_run(run_dir, seed=seed, workers=workers, progress=False)
            diag_path.parent.mkdir(parents=True, exist_ok=True)
            diag_path.write_text(json.dumps(diagnosis, indent=1) + "\n")
        t2 = time.perf_counter()
        _flights, truth_params = read_truth(truth_path)  # only now, after the diagnosis
        scores[name] = {**score_case(diagnosis, truth_params), "set": case.get("set", "validation")}
        timings[name] = {"rig_s": t1 - t0, "diagnose_s": t2 - t1}
        sc = scores[name]
        log(
            f"{name}: true {sc['true'] or ['none']} {sc['outside'] or ''} -> selected "
            f"{sc['selected'] or ['none']}, unexplained {sc['unexplained']}, "
            f"errors {sc['param_errors']} ({t2 - t0:.0f} s)"
        )
    result = scores_record(scores, timings)
    (out_dir / "scores.json").write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
    return result


def merge_results(record: dict, new: dict) -> dict:
    """``record`` (a :func:`run_blind` result) with the cases of ``new`` added or
    replaced, and its summaries (overall and per set) recomputed from the merged cases.
    Why: a change that touches only some cases (or new cases) is re-run alone, and the
    record must still summarize every case."""
    scores = {**record["cases"], **new["cases"]}
    timings = {**record.get("timings", {}), **new.get("timings", {})}
    return scores_record(scores, timings)


def scores_record(scores: dict[str, dict], timings: dict[str, dict]) -> dict:
    """The content of ``scores.json``: per-case ``scores`` and ``timings``, the summary of
    all cases and one per case set (:func:`summarize`)."""
    by_set = {
        k: summarize({n: sc for n, sc in scores.items() if sc["set"] == k})
        for k in CASE_SETS
        if any(sc["set"] == k for sc in scores.values())
    }
    return {"cases": scores, "summary": summarize(scores), "by_set": by_set, "timings": timings}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bouncelab.gap.blind", description=__doc__)
    p.add_argument("--out", required=True, help="output folder (e.g. results/blind)")
    p.add_argument("--cases", default=str(DEFAULT_CASES), help="case file (YAML)")
    p.add_argument("--only", nargs="*", help="run only these case names")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument(
        "--merge-into",
        default=None,
        help="a record (scores.json of an earlier run) to add this run's cases to, in place",
    )
    args = p.parse_args(argv)
    try:
        cases = load_cases(args.cases)
        if args.only:
            cases = [c for c in cases if c["name"] in set(args.only)]
        result = run_blind(cases, args.out, seed=args.seed, workers=args.workers)
        if args.merge_into:
            record = Path(args.merge_into)
            if not record.is_file():
                raise BouncelabError(record, "record to merge into does not exist")
            result = merge_results(json.loads(record.read_text()), result)
            record.write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")
    except BouncelabError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(result["summary"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
