"""The two figures are pure functions of the diagnosis JSON and of scores.json."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

from matplotlib.figure import Figure  # noqa: E402

from bouncelab.figures import fig_blind_validation, fig_gap_diagnosis  # noqa: E402
from bouncelab.figures.style import house_style, save_figure  # noqa: E402


def _diagnosis():
    return {
        "run": "r1",
        "noise_floor": 0.01,
        "baseline": {"model": "ideal", "gap": 0.5},
        "selected": ["friction"],
        "final_gap": 0.012,
        "unexplained": False,
        "regions": [{"gamma_min": 0.8, "gamma_max": 1.2, "gap": 0.01, "explained_by": "friction"}],
        "profile": {
            "gamma": [0.8, 1.0, 1.2, 1.4],
            "heldout": [False, True, False, False],
            "noise_floor": [0.01, 0.01, 0.02, 0.01],
            "gap_baseline": [0.0, 1.0, 0.4, 0.3],
            "gap_after": [{"effect": "friction", "gap": [0.0, 0.01, 0.02, 0.01]}],
        },
    }


def test_gap_diagnosis_figure(tmp_path):
    with house_style():
        fig, data = fig_gap_diagnosis.make(_diagnosis())
    assert isinstance(fig, Figure)
    assert list(data["curves"]) == ["baseline: ideal", "+ friction"]
    save_figure(fig, tmp_path / "g.png", data)
    assert (tmp_path / "g.png").stat().st_size > 0 and (tmp_path / "g.json").is_file()


def test_blind_validation_figure():
    scores = {
        "summary": {
            "labels": ["friction", "none"],
            "confusion": [[2, 0], [0, 1]],
            "top_effect_right": 1.0,
            "null_false_alarms": 0,
            "n_null": 1,
            "n_single": 2,
            "outside_flagged": 1,
            "n_outside": 2,
            "param_errors": {"friction.mu": [0.01, 0.04]},
        }
    }
    with house_style():
        fig, data = fig_blind_validation.make(scores)
    assert isinstance(fig, Figure)
    assert data["confusion"].tolist() == [[2, 0], [0, 1]]
    assert "1 of 2 out-of-library" in data["summary"]
