"""Opening a Parquet file: the one opener of the project's Parquet files (campaigns, traces); pyarrow is the
optional extra ``parquet``, imported only here and only when a Parquet file is read."""

from __future__ import annotations

from pathlib import Path

from ..errors import DataError


def read_parquet(path: Path):
    """``path`` as a pyarrow Table; DataError naming the file when pyarrow is missing or the file is no
    readable Parquet."""
    try:
        import pyarrow.parquet as pq
    except ImportError as e:
        raise DataError(f"{path}: reading Parquet needs pyarrow (pip install 'stiffcomp[parquet]')") from e
    try:
        return pq.read_table(path)
    except Exception as e:  # pyarrow raises several unrelated types for corrupt files
        raise DataError(f"{path}: cannot read Parquet: {e}") from e
