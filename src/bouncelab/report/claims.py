"""The seed's claims (DESIGN.md section 2) beside the values measured here, as one table."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np


def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def relative_flight_time_error(fig7: dict) -> float | None:
    """Median over shared steps of |T_data - T_model| / T_model (per-step medians)."""
    dg = np.asarray(fig7.get("data_gamma") or [], dtype=float)
    dt = np.asarray(fig7.get("data_median_T_periods") or [], dtype=float)
    mg = np.asarray(fig7.get("model_gamma") or [], dtype=float)
    mt = np.asarray(fig7.get("model_median_T_periods") or [], dtype=float)
    if not (dg.size and mg.size):
        return None
    common, i, j = np.intersect1d(dg, mg, return_indices=True)
    ok = mt[j] > 0
    if not ok.any():
        return None
    return float(np.median(np.abs(dt[i][ok] - mt[j][ok]) / mt[j][ok]))


def claims_table(results: Path, sweeps: list[str], drops: list[str], checks: dict) -> dict:
    """Table block: claim, the seed's value, ours (with the run it comes from), verdict."""
    rows = []
    # every drop run's calibration, as every sweep gets its rows: with several drop tests
    # (other bodies, other rigs) the first by name alone stood for all of them
    calibrations = [(r, _read_json(results / "runs" / r / "calibration.json")) for r in drops]
    calibrations = [(r, cal) for r, cal in calibrations if cal]
    for run, cal in calibrations:
        mu, (lo, hi) = cal["mu"], cal["mu_ci"]
        rows.append(
            [
                "friction on the guide (drop test)",
                "about 0.29 g",
                f"{mu:.3f} [{lo:.3f}, {hi:.3f}] ({run})",
                "agrees" if lo - 0.02 <= 0.29 <= hi + 0.02 else "differs",
            ]
        )
        e, (lo, hi) = cal["restitution"], cal["restitution_ci"]
        rows.append(
            [
                "coefficient of restitution (drop test)",
                "about 0.515",
                f"{e:.3f} [{lo:.3f}, {hi:.3f}] ({run})",
                "agrees" if lo - 0.02 <= 0.515 <= hi + 0.02 else "differs",
            ]
        )
    if not calibrations:
        rows.append(["friction and restitution (drop test)", "0.29 g, 0.515", "no drop run", "-"])

    for run in sweeps:
        fig7 = _read_json(results / "figures" / run / "fig07_bifurcation.json")
        err = relative_flight_time_error(fig7) if fig7 else None
        rows.append(
            [
                f"flight-time error of the ideal model ({run})",
                "1/2 to 2/3 of the prediction",
                f"median {err:.2f} of the prediction" if err is not None else "-",
                "-" if err is None else ("agrees" if 0.4 <= err <= 0.75 else "differs"),
            ]
        )
        info = (checks.get(run) or {}).get("info") or {}
        gaps = info.get("gamma_gaps") or []
        rows.append(
            [
                f"data gaps in Gamma ({run})",
                "1.75-1.95 and 4.55-4.85",
                ", ".join(f"{a:g}-{b:g}" for a, b in gaps) or "none",
                "kept as gaps, not errors" if gaps else "-",
            ]
        )
        fig10 = _read_json(results / "figures" / run / "fig10_harmonic.json")
        fig9 = _read_json(results / "figures" / run / "fig09_friction.json")
        if fig10 and fig9:
            h = fig10.get("median_abs_diff_periods")
            i = fig9.get("ideal_median_abs_diff_periods")
            f = fig9.get("friction_median_abs_diff_periods")
            if None not in (h, i, f):
                best = min((i, "ideal"), (f, "friction"), (h, "harmonic"))[1]
                rows.append(
                    [
                        f"friction and harmonic models closer to the data ({run})",
                        "friction brings the model closer; a harmonic resembles the data "
                        "beyond Gamma 2",
                        f"median |data - model|: ideal {i:.3f}, friction {f:.3f}, "
                        f"harmonic {h:.3f} periods",
                        f"closest: {best}",
                    ]
                )
    energy_note = "see the energy section"
    rows.append(["energy lost to friction at Gamma 3.4, T = 0.11 s", "0.0122 J", energy_note, "-"])
    rows.append(["energy gained from restitution, same flight", "0.00498 J", energy_note, "-"])
    for r in rows:
        r[:] = [x if not (isinstance(x, float) and math.isnan(x)) else "-" for x in r]
    return {
        "type": "table",
        "caption": "The seed's claims and the values measured here",
        "header": ["claim", "seed", "here", "verdict"],
        "rows": rows,
    }
