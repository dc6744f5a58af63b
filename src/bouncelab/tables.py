"""Reading and writing tables by file extension (``.parquet`` or ``.csv``)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from bouncelab.errors import BouncelabError

TABLE_SUFFIXES = (".parquet", ".csv")


def write_table(df: pd.DataFrame, path: str | Path) -> Path:
    """Write ``df`` to ``path`` as Parquet or CSV, chosen by the extension.

    The output is deterministic: no index, no timestamps in the file.
    Parent folders are created.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in TABLE_SUFFIXES:
        raise BouncelabError(
            path, f"output must end in .parquet or .csv, not {suffix or 'nothing'!r}"
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".parquet":
        df.to_parquet(path, index=False, engine="pyarrow", compression="zstd")
    else:
        df.to_csv(path, index=False, float_format="%.10g")
    return path


def read_table(path: str | Path) -> pd.DataFrame:
    """Read a table written by :func:`write_table`."""
    path = Path(path)
    suffix = path.suffix.lower()
    if not path.is_file():
        raise BouncelabError(path, "table file not found")
    if suffix == ".parquet":
        return pd.read_parquet(path, engine="pyarrow")
    if suffix == ".csv":
        return pd.read_csv(path)
    raise BouncelabError(path, f"table must end in .parquet or .csv, not {suffix!r}")
