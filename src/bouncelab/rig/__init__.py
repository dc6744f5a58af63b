"""The virtual rig: a dimensional, time-stepped simulator of the lab (docs/rig.md).

Written independently of :mod:`bouncelab.physics` (a second, higher-fidelity model:
compliant contact, regularised Coulomb friction, a shaker armature pushed by the
impacts, a sensor chain), so that comparing the two means something.

    run_rig(config_path, out_dir, truth_path=None)   # what `bouncelab rig` does
    flights, params = read_truth(truth_path)
"""

from __future__ import annotations

from pathlib import Path

from bouncelab.errors import BouncelabError
from bouncelab.rig.config import derive, load_rig_config, parse_rig_config
from bouncelab.rig.simulate import RigResult, simulate_rig
from bouncelab.rig.truth import read_truth, write_truth
from bouncelab.rig.writers import write_run

__all__ = [
    "RigResult",
    "derive",
    "load_rig_config",
    "parse_rig_config",
    "read_truth",
    "run_rig",
    "simulate_rig",
    "write_run",
    "write_truth",
]


def run_rig(
    config_path: str | Path, out_dir: str | Path, truth_path: str | Path | None = None,
    force: bool = False,
) -> RigResult:  # fmt: skip
    """Simulate the config at ``config_path``, write the run folder ``out_dir`` and,
    if given, the ground truth to ``truth_path`` (which must lie outside ``out_dir``).

    Returns the :class:`RigResult`. Raises :class:`BouncelabError` for bad input.
    """
    out_dir = Path(out_dir)
    if truth_path is not None:
        truth_path = Path(truth_path)
        if truth_path.resolve().is_relative_to(out_dir.resolve()):
            raise BouncelabError(truth_path, "the truth file must lie outside the run folder")
        if truth_path.suffix.lower() != ".parquet":
            raise BouncelabError(truth_path, "truth file must end in .parquet")
    cfg = load_rig_config(config_path)
    result = simulate_rig(cfg)
    rec = cfg["recording"]
    write_run(result, out_dir, rec["format"], rec["csv_time_column"], force=force)
    if truth_path is not None:
        write_truth(result.truth, result.params, truth_path)
    return result
