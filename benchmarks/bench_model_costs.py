"""What one evaluation of the diagnosis's objective costs, per model and per run.

The diagnosis's budgets (``gap.fit.DIAGNOSIS_CYCLES``, ``REFINE_CYCLES``,
``FEEDBACK_SEARCH_CYCLES``) count simulated drive cycles, whatever the model. This
measures what a cycle costs: one :func:`bouncelab.gap.fit.step_gaps` evaluation (the
4-member ensemble of a diagnosis, the gaps to the data included) on one thread, as an
:class:`~bouncelab.gap.fit.EvaluationPool` worker runs it, for every model the selection
fits (the ideal ball and up to three effects together), on recordings of the independent
generator (``independent_rig.py``) of three protocols. The numbers are what a budget
counting the cost of a simulation, not its cycles, would be built on (docs/diagnosis.md
section 5).

Measures, prints and writes ``benchmarks/results/model_costs.json``.
Run: ``python benchmarks/bench_model_costs.py [--seconds 1.0]`` (about 2 minutes).
"""

from __future__ import annotations

import argparse
import itertools
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

from bouncelab.flights import extract_run
from bouncelab.gap.fit import FitSettings, make_problem, problem_cycles, step_gaps
from bouncelab.physics import EFFECT_ORDER, Model
from bouncelab.physics.simulate import OutputBuffer
from bouncelab.runs import load_run

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_independent import CASES  # noqa: E402
from independent_rig import make_case  # noqa: E402

OUT = Path(__file__).resolve().parent / "results" / "model_costs.json"

#: The runs: the two independent cases over the 2-minute goal and a harmonic one.
RUNS = ("seed_like_impacts_only", "vibration_27hz", "harmonic_k3")

#: Each library effect at a typical strength (CONTRACTS.md section 5).
TYPICAL = {
    "friction": {"mu": 0.25},
    "restitution": {"e": 0.5},
    "harmonic": {"k": 2.0, "a": 0.05, "psi": 1.0},
    "feedback": {"mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.05, "ride_load": 0.0},
    "gamma_scale": {"s": 1.02},
}

#: Every model the diagnosis fits: the ideal ball and one to three effects together
#: (``select.SelectSettings.max_effects``), in the library's order.
MODELS = {"ideal": {}} | {
    "+".join(combo): {k: v for e in combo for k, v in TYPICAL[e].items()}
    for n in (1, 2, 3)
    for combo in itertools.combinations(EFFECT_ORDER, n)
}


def evaluation_ms(problem, model: Model, seconds: float) -> float:
    """Mean wall time (ms) of one evaluation of ``model`` on ``problem``, repeated for
    ``seconds`` after one warm-up call."""
    buffer = OutputBuffer()
    step_gaps(problem, model, buffer)
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        step_gaps(problem, model, buffer)
        n += 1
    return (time.perf_counter() - t0) / n * 1e3


def main() -> None:
    import numba

    p = argparse.ArgumentParser()
    p.add_argument("--seconds", type=float, default=1.0, help="timing per model and run")
    args = p.parse_args()
    numba.set_num_threads(1)  # as a pool worker runs
    settings = FitSettings()
    record = {"runs": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name in RUNS:
            run_dir = Path(tmp) / name
            make_case(run_dir, **CASES[name])
            table, qc = extract_run(run_dir)
            problem = make_problem(
                load_run(run_dir), table, float(qc["t_end_s"].max()),
                n_members=settings.n_members, heldout_every=settings.heldout_every,
            )  # fmt: skip
            cycles = problem_cycles(problem)
            costs = {}
            for model, params in MODELS.items():
                ms = evaluation_ms(problem, Model.parse(model, params), args.seconds)
                costs[model] = {"ms": ms, "us_per_cycle": ms * 1e3 / cycles}
            ideal = costs["ideal"]["us_per_cycle"]
            for c in costs.values():
                c["relative_to_ideal"] = c["us_per_cycle"] / ideal
            record["runs"][name] = {"cycles": cycles, "costs": costs}
            print(f"{name} ({cycles:.0f} cycles a simulation, one thread):", flush=True)
            for model, c in costs.items():
                print(
                    f"  {model:40s} {c['ms']:7.1f} ms  {c['us_per_cycle']:6.2f} us/cycle  "
                    f"x{c['relative_to_ideal']:.1f} of ideal",
                    flush=True,
                )
    record["machine"] = {
        "machine": platform.machine(),
        "python": platform.python_version(),
        "numba": numba.__version__,
    }
    OUT.write_text(json.dumps(record, indent=1) + "\n")
    print(f"-> {OUT}")


if __name__ == "__main__":
    main()
