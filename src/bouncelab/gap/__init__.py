"""The sim-to-real gap: distances, noise floor, features, regions.

Distances per Gamma step between measured and simulated flights
(:mod:`bouncelab.gap.distances`), the noise floor they are judged against
(:mod:`bouncelab.gap.noise`), named features that differ (:mod:`bouncelab.gap.features`)
and the segmentation of the gap over Gamma into regions (:mod:`bouncelab.gap.regions`).
All flight times and distances are in radians of drive phase; see ``docs/gap.md``.
"""

from bouncelab.gap.distances import (
    FlightSample,
    gap_table,
    overall_gap,
    prepare_flights,
    projection_directions,
    return_map_pairs,
    sliced_wasserstein_2d,
    step_distances,
    step_grid,
    step_weights,
    wasserstein_1d,
)
from bouncelab.gap.features import (
    FeatureOptions,
    compare_features,
    count_clusters,
    features,
    step_features,
)
from bouncelab.gap.noise import (
    noise_floor,
    null_relative_gaps,
    overall_relative_gap,
    relative_gap,
    split_halves,
)
from bouncelab.gap.regions import segment_profile, segment_regions

__all__ = [
    "FeatureOptions",
    "FlightSample",
    "compare_features",
    "count_clusters",
    "features",
    "gap_table",
    "noise_floor",
    "null_relative_gaps",
    "overall_gap",
    "overall_relative_gap",
    "prepare_flights",
    "projection_directions",
    "relative_gap",
    "return_map_pairs",
    "segment_profile",
    "segment_regions",
    "sliced_wasserstein_2d",
    "split_halves",
    "step_distances",
    "step_features",
    "step_grid",
    "step_weights",
    "wasserstein_1d",
]


def __getattr__(name: str):
    """``diagnose_run`` and ``diagnose_flights`` on first use: they pull in the simulator,
    which the distance functions above do not need."""
    if name in ("diagnose_run", "diagnose_flights"):
        from bouncelab.gap import diagnose

        return getattr(diagnose, name)
    raise AttributeError(f"module 'bouncelab.gap' has no attribute {name!r}")
