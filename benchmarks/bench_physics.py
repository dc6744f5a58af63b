"""Speed of the physics kernels: flights per second per model, compile time, reference ratio.

Run: ``python benchmarks/bench_physics.py [--quick] [--repeat N]``.  Prints the best and
the median of N repetitions (the machine may be shared) and writes
``benchmarks/results/physics.json``.  Goals (issue 2): ideal >= 1e7 flights/s on 2 cores
after compilation, every other model >= 2e6/s, >= 1000x the plain-Python reference
(sign scan + brentq), a 4000 Gamma x 1000 flight bifurcation diagram in < 1 s.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

from bouncelab.physics import Model, simulate_grid
from bouncelab.physics import kernels as K
from bouncelab.physics.reference import reference_flights
from bouncelab.physics.simulate import _NO_END, kernel_params

MODELS = {
    "ideal": {},
    "friction": {"mu": 0.29},
    "restitution": {"e": 0.515},
    "harmonic": {"k": 3.0, "a": 0.1},
    "feedback": {"mass_ratio": 0.05, "f_ratio": 0.5, "zeta": 0.1},
    "gamma_scale": {"s": 1.1},
    "friction+restitution+harmonic+feedback": {"mu": 0.29, "e": 0.515},
}
OUT = Path(__file__).parent / "results" / "physics.json"


def kernel_rates(
    model: Model, gammas: np.ndarray, n_flights: int, repeat: int = 5, fast: bool = True
) -> list[float]:
    """Flights per second of the compiled kernel alone (no DataFrame), one per repetition.

    ``fast=False`` runs pure sine plates through the general solver (the kernel before
    the fast path), for the before/after figure.
    """
    n = gammas.size
    hk, ha, hp = model.harmonic_arrays()
    out = np.empty((K.NCOL, n * n_flights))
    args = (
        kernel_params(model, fast), hk, ha, hp, model.gamma_true(gammas)[:, None],
        gammas[:, None], np.array([_NO_END]), True, np.zeros(n), np.zeros(n), np.zeros(n), 0,
        n_flights, 0, np.zeros(n), out,
    )  # fmt: skip
    rates = []
    for _ in range(repeat):
        t = time.perf_counter()
        rows, _ = K.run_many(*args)
        rates.append(rows.sum() / (time.perf_counter() - t))
    return rates


def evals_per_flight(model: Model, gammas: np.ndarray, n_flights: int) -> float:
    """Mean plate evaluations of the landing search per flight (column ``C_NSTEPS``)."""
    n = gammas.size
    hk, ha, hp = model.harmonic_arrays()
    out = np.empty((K.NCOL, n * n_flights))
    rows, _ = K.run_many(
        kernel_params(model), hk, ha, hp, model.gamma_true(gammas)[:, None], gammas[:, None],
        np.array([_NO_END]), True, np.zeros(n), np.zeros(n), np.zeros(n), 0, n_flights, 0,
        np.zeros(n), out,
    )  # fmt: skip
    keep = (np.arange(n_flights)[None, :] < rows[:, None]).ravel()
    return float(out[K.C_NSTEPS][keep].mean())


def kernel_rate(model: Model, gammas: np.ndarray, n_flights: int, repeat: int = 3) -> float:
    """Best of :func:`kernel_rates` (flights per second)."""
    return max(kernel_rates(model, gammas, n_flights, repeat))


def machine_speed(repeat: int = 3) -> float:
    """This machine's speed for the diagnosis's timings: the armature (``feedback``)
    kernel's best rate in millions of flights per second on one thread (100 Gamma values
    over 1.1-8, 200 flights each; about a second). Why: the diagnosis's time is mostly
    armature simulations, and the same code took 1.3 times longer on one session's
    machine than on another's; a time recorded beside this rate can be compared across
    machines (``feedback`` of ``physics.json`` is the same kernel on a larger workload,
    on all of numba's threads).
    """
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        m = Model.parse("feedback", MODELS["feedback"])
        gammas = np.linspace(1.1, 8.0, 100)
        kernel_rate(m, gammas[:4], 10, repeat=1)  # load from cache / compile
        return round(kernel_rate(m, gammas, 200, repeat) / 1e6, 3)
    finally:
        numba.set_num_threads(threads)


def compile_seconds() -> float:
    """Cold compile time: first simulate_grid call in a fresh process with an empty cache."""
    code = (
        "import time; t=time.perf_counter(); from bouncelab.physics import Model, simulate_grid;"
        "simulate_grid(Model.parse('ideal'), [2.0], 2); print(time.perf_counter()-t)"
    )
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
        r = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
    return float(r.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="smaller workloads")
    ap.add_argument("--repeat", type=int, default=5, help="repetitions (best and median)")
    args = ap.parse_args()
    n_g, n_f = (500, 400) if args.quick else (2000, 1000)
    gammas = np.linspace(1.1, 8.0, n_g)  # Gamma <= 1 has no flights: not a fair workload
    res: dict = {
        "machine": {
            "python": platform.python_version(),
            "numba": numba.__version__,
            "cpus": os.cpu_count(),
            "threads": numba.get_num_threads(),
            "load_avg": os.getloadavg(),
        },
        "workload": {"gammas": [1.1, 8.0, n_g], "flights_per_gamma": n_f},
        "goals": {"ideal": 1e7, "other": 2e6, "reference_ratio": 1000, "bifurcation_s": 1.0},
    }
    res["compile_s"] = compile_seconds()
    print(f"cold compile (empty cache): {res['compile_s']:.1f} s")

    rates, medians, general, evals = {}, {}, {}, {}
    for name, params in MODELS.items():
        m = Model.parse(name, params)
        kernel_rate(m, gammas[:4], 10, repeat=1)  # load from cache / compile
        r = kernel_rates(m, gammas, n_f, repeat=args.repeat)
        rates[name], medians[name] = max(r), float(np.median(r))
        evals[name] = evals_per_flight(m, gammas[:: max(1, n_g // 500)], 200)
        line = f"{name:42s} best {rates[name] / 1e6:6.2f}  median {medians[name] / 1e6:6.2f} M/s"
        line += f"  ({evals[name]:.2f} evals/flight)"
        if not m.harmonic_arrays()[0].size and not m.params.get("mass_ratio", 0.0):
            general[name] = max(kernel_rates(m, gammas, n_f, repeat=2, fast=False))
            line += f"   (general solver {general[name] / 1e6:5.2f})"
        print(line)
    res["flights_per_s"] = rates
    res["flights_per_s_median"] = medians
    res["flights_per_s_general_solver"] = general
    res["landing_evals_per_flight"] = evals

    # plain-Python reference on a few Gammas, the kernel on the same workload
    ref_g = np.linspace(1.1, 8.0, 8)
    ref_n = 100
    t = time.perf_counter()
    n_ref = sum(len(reference_flights(g, ref_n)) for g in ref_g)
    ref_rate = n_ref / (time.perf_counter() - t)
    same = kernel_rate(Model.parse("ideal"), np.repeat(ref_g, 250), ref_n)
    res["reference"] = {"flights_per_s": ref_rate, "kernel_same_workload": same}
    res["reference_ratio"] = same / ref_rate
    ratio = res["reference_ratio"]
    print(f"reference (scan + brentq): {ref_rate:,.0f} flights/s; ratio {ratio:,.0f}x")

    # bifurcation diagram: 4000 Gamma x 1000 flights, Gamma 0..8, DataFrame included
    g4000 = np.linspace(0.0, 8.0, 4000)
    nb = 250 if args.quick else 1000
    simulate_grid(Model.parse("ideal"), g4000[:4], 2)
    times = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        df = simulate_grid(Model.parse("ideal"), g4000, nb)
        times.append(time.perf_counter() - t)
        n_rows = len(df)
        del df  # (frees the table before the next run)
    best, med = min(times), float(np.median(times))
    res["bifurcation"] = {
        "gammas": 4000, "flights": nb, "rows": n_rows, "seconds": best, "median_s": med,
    }  # fmt: skip
    print(f"bifurcation 4000 x {nb}: best {best:.2f} s, median {med:.2f} s (DataFrame included)")

    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(res, indent=2) + "\n")
    print(f"-> {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
