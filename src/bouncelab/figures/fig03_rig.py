"""Seed fig. 3 (photographs in the seed): a schematic of the rig with a run's parameters."""

from __future__ import annotations

from matplotlib.patches import FancyArrowPatch, Rectangle

from bouncelab.figures.style import new_figure


def parameter_lines(params: dict) -> list[str]:
    """Lines of text describing the run (only what is known)."""
    lines = [f"run: {params.get('run_id', '?')} ({params.get('kind', '?')})"]
    if params.get("source"):
        lines.append(f"source: {params['source']}")
    if params.get("mass_kg") is not None:
        lines.append(f"mass: {1e3 * params['mass_kg']:.0f} g")
    if params.get("drive_frequency_hz") is not None:
        lines.append(f"drive frequency: {params['drive_frequency_hz']:g} Hz")
    if params.get("sample_rate_hz") is not None:
        lines.append(f"sampling: {params['sample_rate_hz'] / 1e3:g} kHz")
    if params.get("gamma_min") is not None:
        lines.append(
            f"Gamma {params['gamma_min']:g} to {params['gamma_max']:g} "
            f"in {params.get('n_steps', '?')} steps"
        )
    if params.get("settle_cycles") is not None and params.get("kind") == "sweep":
        lines.append(f"settle cycles: {params['settle_cycles']}")
    if params.get("drop_height_m") is not None:
        lines.append(f"drop height: {1e3 * params['drop_height_m']:g} mm")
    if params.get("duration_s") is not None:
        lines.append(f"recording: {params['duration_s']:.1f} s")
    if params.get("channels"):
        lines.append("channels: " + ", ".join(sorted(params["channels"])))
    return lines


def make(params: dict):
    """Schematic: shaker, plate, guide pole, mass, continuity circuit, and the run's numbers."""
    fig, ax = new_figure(width_in=7.0, height_in=3.6)
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 6)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.grid(False)
    # shaker body and armature
    ax.add_patch(Rectangle((1.0, 0.3), 2.6, 1.2, fc="#bbbbbb", ec="k", lw=0.8))
    ax.text(2.3, 0.9, "shaker", ha="center", va="center", fontsize=8)
    ax.add_patch(Rectangle((2.15, 1.5), 0.3, 0.5, fc="#888888", ec="k", lw=0.8))
    # plate
    ax.add_patch(Rectangle((0.8, 2.0), 3.0, 0.18, fc="#4a6fa5", ec="k", lw=0.8))
    ax.text(0.6, 2.09, "plate", ha="right", va="center", fontsize=8)
    # guide pole, fixed to the lab frame (frame drawn at the top)
    ax.add_patch(Rectangle((2.25, 2.18), 0.1, 3.3, fc="#dddddd", ec="k", lw=0.6))
    ax.plot([1.2, 3.4], [5.5, 5.5], color="k", lw=1.5)
    ax.text(3.5, 5.5, "frame", va="center", fontsize=8)
    # mass on the pole
    ax.add_patch(Rectangle((1.85, 3.2), 0.9, 0.6, fc="#c49a3a", ec="k", lw=0.8))
    ax.text(2.9, 3.5, "mass", va="center", fontsize=8)
    ax.add_patch(
        FancyArrowPatch((1.6, 2.5), (1.6, 3.1), arrowstyle="<->", mutation_scale=8, lw=0.8)
    )
    ax.text(1.5, 2.8, "flight", ha="right", va="center", fontsize=7)
    ax.add_patch(
        FancyArrowPatch((4.1, 1.6), (4.1, 2.4), arrowstyle="<->", mutation_scale=8, lw=0.8)
    )
    ax.text(4.2, 2.0, r"$A\sin\omega t$", va="center", fontsize=8)
    # continuity circuit: mass and plate close it on contact
    ax.plot([2.75, 5.0, 5.0], [3.5, 3.5, 3.0], color="#d62728", lw=0.8)
    ax.plot([3.8, 5.0, 5.0], [2.09, 2.09, 2.5], color="#d62728", lw=0.8)
    ax.add_patch(Rectangle((4.75, 2.5), 0.5, 0.5, fc="white", ec="#d62728", lw=0.8))
    ax.text(5.35, 2.75, "continuity circuit\n-> ADC", va="center", fontsize=7, color="#d62728")
    ax.text(
        6.6,
        5.6,
        "\n".join(parameter_lines(params)),
        va="top",
        ha="left",
        fontsize=7.5,
        family="DejaVu Sans Mono",
    )
    fig.tight_layout()
    data = dict(params)
    data["summary"] = "; ".join(parameter_lines(params)) + "."
    return fig, data
