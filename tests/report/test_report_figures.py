"""Line styles of the model variants, the legend under many-line figures, and labels that
stay on the canvas."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import yaml  # noqa: E402

from bouncelab.figures import (
    fig04_accelerometer,
    fig05_continuity,
    fig08_return_maps,
    fig_energy_budget,
    fig_gap_over_gamma,
)  # noqa: E402
from bouncelab.figures.style import (  # noqa: E402
    DATA_COLOR,
    VARIANT_COLORS,
    house_style,
    variant_styles,
)

REPO = Path(__file__).resolve().parents[2]


def _config_variants() -> list[str]:
    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    return list(config["variants"])


def test_every_default_variant_has_its_own_line():
    names = _config_variants()
    styles = variant_styles(names)
    assert list(styles) == names
    lines = {(s["color"], s["ls"]) for s in styles.values()}
    assert len(lines) == len(names)
    # and its own colour, not only its own dash: the default set fits the palette
    assert len({s["color"] for s in styles.values()}) == len(names)


def test_ideal_is_black_and_combinations_are_dashed():
    styles = variant_styles(["friction", "ideal", "friction+restitution"])
    assert styles["ideal"] == {"color": DATA_COLOR, "ls": "-"}
    assert styles["friction"] == {"color": VARIANT_COLORS[0], "ls": "-"}
    assert styles["friction+restitution"] == {"color": VARIANT_COLORS[1], "ls": "--"}


def test_colours_repeat_dotted_past_the_palette():
    names = [f"m{i}" for i in range(len(VARIANT_COLORS) + 2)]
    styles = variant_styles(names)
    assert styles[names[-1]] == {"color": VARIANT_COLORS[1], "ls": ":"}
    assert len({(s["color"], s["ls"]) for s in styles.values()}) == len(names)


def _table(names, column):
    gamma = np.linspace(1.0, 4.0, 7)
    rows = [
        {"variant": n, "step": k, "gamma": g, column: 1.0 + i + g, "floor_used": 1.0}
        for i, n in enumerate(names)
        for k, g in enumerate(gamma)
    ]
    return pd.DataFrame(rows)


def _compare(rel_by_variant: dict, gamma) -> pd.DataFrame:
    rows = [
        {"variant": v, "step": k, "gamma": g, "rel_gap": r, "gap": r, "floor_used": 1.0}
        for v, rels in rel_by_variant.items()
        for k, (g, r) in enumerate(zip(gamma, rels, strict=True))
    ]
    return pd.DataFrame(rows)


def test_closest_variant_per_step():
    compare = _compare(
        {
            "ideal": [5.0, 0.5, 3.0, 2.0, np.nan],
            "friction": [2.0, 0.9, 4.0, 2.0, 1.0],
            "friction+restitution": [3.0, 0.2, 1.5, 2.5, 3.0],
        },
        [1.0, 1.1, 1.2, 1.3, 1.4],
    )
    best = fig_gap_over_gamma.closest_by_step(compare)
    assert best["step"].tolist() == [0, 1, 2, 3, 4]
    # step 1: every variant within the floor, so none is closest; step 3: a tie goes
    # to the variant listed first; step 4: a missing gap leaves the others to compete
    assert best["variant"].tolist() == [
        "friction",
        None,
        "friction+restitution",
        "ideal",
        "friction",
    ]


def test_closest_strip_leaves_a_data_gap_blank():
    gamma = [1.0, 1.1, 1.2, 1.8, 1.9]  # no step between 1.2 and 1.8
    compare = _compare({"ideal": [2.0] * 5, "friction": [3.0] * 5}, gamma)
    with house_style():
        fig, data = fig_gap_over_gamma.make(compare, "r")
    strip = fig.axes[1]
    assert len(strip.patches) == 5  # one bar per step
    covered = [(p.get_x(), p.get_x() + p.get_width()) for p in strip.patches]
    assert not any(lo < g < hi for lo, hi in covered for g in (1.3, 1.5, 1.7))
    assert data["variants"]["ideal"]["closest_steps"] == 5
    assert "ideal at 5" in data["summary"]


def test_variant_figures_draw_each_variant_with_its_style_and_keep_the_legend_clear():
    names = _config_variants()
    styles = variant_styles(names)
    compare = _table(names, "rel_gap").assign(gap=lambda d: d["rel_gap"])
    budget = _table(names, "friction_j").assign(impact_j=1e-3, plate_j=2e-3)
    with house_style():
        figures = [
            fig_gap_over_gamma.make(compare, "r")[0],
            fig_energy_budget.make(budget, "r")[0],
        ]
    for fig in figures:
        (legend,) = fig.legends  # one, under the axes, not inside them
        assert [t.get_text() for t in legend.get_texts()] == names
        fig.canvas.draw()
        legend_top = legend.get_window_extent().y1
        for ax in fig.axes:
            assert ax.get_legend() is None
            assert ax.get_tightbbox().y0 >= legend_top - 1.0  # the axis labels clear it
            for line in ax.get_lines():
                if line.get_label() in styles:
                    want = styles[line.get_label()]
                    assert matplotlib.colors.same_color(line.get_color(), want["color"])
                    assert line.get_linestyle() == want["ls"]


def test_return_maps_keep_their_axis_labels_on_the_canvas():
    # the square panels once pushed the T_n labels below the figure's bottom edge
    rng = np.random.default_rng(0)
    flights = pd.DataFrame(
        {
            "gamma": np.repeat([2.0, 3.6, 3.9], 40),
            "step": np.repeat([0, 1, 2], 40),
            "T": rng.uniform(0.1, 14.0, 120),
            "settled": True,
        }
    )
    with house_style():
        fig, _ = fig08_return_maps.make(flights, [2.0, 3.6, 3.9], "r")
    fig.canvas.draw()
    for ax in fig.axes:
        box = ax.get_tightbbox()
        assert box.y0 >= 0.0 and box.x0 >= 0.0
        assert box.y1 <= fig.bbox.height and box.x1 <= fig.bbox.width


def _square_wave(fs, t_stop, flights):
    """A continuity signal at 5 V during ``flights`` ((takeoff, landing) s), 0 V between."""
    t = np.arange(0.0, t_stop, 1.0 / fs)
    v = np.zeros_like(t)
    for a, b in flights:
        v[(t >= a) & (t < b)] = 5.0
    return t, v


def test_continuity_figure_magnifies_the_contact_nearest_the_middle():
    # three flights with 0.2 ms contacts between them: the one nearest the middle is shown
    pairs = [(0.010, 0.050), (0.0502, 0.090), (0.0902, 0.130)]
    t, v = _square_wave(20_000.0, 0.14, pairs)
    flights = pd.DataFrame(pairs, columns=["t_takeoff_s", "t_landing_s"])
    with house_style():
        fig, data = fig05_continuity.make(t, v, flights, "r", gamma=2.5)
    assert data["n_flights"] == 3
    assert data["contact_shown_s"] == [0.050, 0.0502]  # middle at 0.0501 s, the stretch's 0.07
    assert len(fig.axes) == 2
    zoom = fig.axes[1]
    (samples,) = [ln for ln in zoom.get_lines() if ln.get_marker() == "."]
    lo, hi = samples.get_xdata().min(), samples.get_xdata().max()
    assert lo < 0.0 < 0.2 < hi  # both edges of the 0.2 ms contact, with samples around
    assert hi - lo < 1.0  # magnified: about a millisecond, not the 140 ms stretch


def test_continuity_figure_without_a_contact_says_so():
    t, v = _square_wave(20_000.0, 0.05, [(0.010, 0.040)])
    flights = pd.DataFrame([(0.010, 0.040)], columns=["t_takeoff_s", "t_landing_s"])
    with house_style():
        fig, data = fig05_continuity.make(t, v, flights, "r")
    assert data["contact_shown_s"] is None
    assert "no contact" in fig.axes[1].texts[0].get_text()


def _accel_figure_inputs(gamma_by_step):
    t = np.arange(2000) / 20_000.0
    accel = 0.03 * np.sin(2 * np.pi * 35.0 * t)
    return {
        "time_s": t,
        "accel_v": accel,
        "residual_v": accel * 0.01,
        "continuity_landings_s": np.array([0.02, 0.05]),
        "comparison": pd.DataFrame({"diff_s": [-0.001, 0.0005, np.nan]}),
        "summary": {"n_continuity": 3, "n_accel": 2, "share_found": 2 / 3,
                    "share_false": 0.0, "median_abs_error_s": 7.5e-4, "p99_abs_error_s": 1e-3},
        "run_id": "r",
        "gamma": 3.0,
        "gamma_by_step": gamma_by_step,
    }  # fmt: skip


def test_accelerometer_figure_shows_the_gamma_it_reads_when_it_can():
    by_step = pd.DataFrame(
        {
            "step": [0, 1, 2],
            "gamma": [1.0, 2.0, 3.0],
            "gamma_accel": [0.93, 1.862, 2.79],
            "gamma_accel_se": [0.004, 0.004, 0.004],
            "n_samples": [20000] * 3,
            "a3": [0.08, 0.0801, 0.0799],
            "a3_se": [0.001] * 3,
            "psi3": [1.0, 1.01, 0.99],
        }
    )
    with house_style():
        fig, data = fig04_accelerometer.make(**_accel_figure_inputs(by_step))
    assert len(fig.axes) == 4
    assert abs(data["gamma_scale"]["s"] - 0.93) < 1e-9  # the median of 0.93, 0.931, 0.93
    assert [h["k"] for h in data["harmonics"]] == [3]
    assert "0.93 x the stated" in data["summary"] and "k = 3" in data["summary"]
    with house_style():
        fig, data = fig04_accelerometer.make(**_accel_figure_inputs(None))
    assert len(fig.axes) == 3 and "gamma_scale" not in data
