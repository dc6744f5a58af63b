"""The ground truth of a rig run: a Parquet file kept outside the run folder.

One row per true flight (``simulate.TRUTH_COLUMNS``: step, stated and true Gamma,
takeoff and landing times in s, flight time in s and in radians of drive phase, relative
velocities at takeoff and impact in m/s) and, as JSON in the Parquet key-value metadata
under ``bouncelab.rig``, every parameter: the full config (defaults filled) and the
derived numbers (contact stiffness and damping, step schedule, ...).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from bouncelab.errors import BouncelabError

META_KEY = b"bouncelab.rig"


def write_truth(flights: pd.DataFrame, params: dict, path: str | Path) -> Path:
    """Write the truth table and parameters to ``path`` (``.parquet``); deterministic."""
    path = Path(path)
    if path.suffix.lower() != ".parquet":
        raise BouncelabError(path, "truth file must end in .parquet")
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(flights, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    meta[META_KEY] = json.dumps(params, sort_keys=True, allow_nan=False).encode()
    table = table.replace_schema_metadata(meta)
    pq.write_table(table, path, compression="zstd")
    return path


def read_truth(path: str | Path) -> tuple[pd.DataFrame, dict]:
    """Read a truth file: ``(flights DataFrame, params dict)``."""
    path = Path(path)
    if not path.is_file():
        raise BouncelabError(path, "truth file not found")
    try:
        table = pq.read_table(path)
    except (pa.ArrowInvalid, OSError) as exc:
        raise BouncelabError(path, f"not a readable Parquet file ({exc})") from None
    meta = table.schema.metadata or {}
    if META_KEY not in meta:
        raise BouncelabError(path, "not a rig truth file (no bouncelab.rig metadata)")
    return table.to_pandas(), json.loads(meta[META_KEY])
