"""Per-episode metrics as a columnar file (one file per cell).

The writer goes through :func:`oneocean.io.atomic_path` and returns a manifest entry
``{path, sha256, bytes, kind, rows, columns, ...meta}``. Parquet bytes depend only on the data
(pyarrow writes no timestamps; the ``created_by`` string is the library version), which the
tests check.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

from ..errors import ConfigError
from ..io import atomic_path, sha256_file

if TYPE_CHECKING:  # pandas / pyarrow are imported lazily (they cost ~0.6 s per process)
    import pandas as pd
    import pyarrow as pa

_PARQUET_OPTS = dict(compression="zstd", use_dictionary=False, write_statistics=False)


def _write_table(table: pa.Table, path: Path) -> None:
    import pyarrow.parquet as pq

    with atomic_path(path, suffix=".parquet") as tmp:
        pq.write_table(table, tmp, **_PARQUET_OPTS)


def _entry(path: Path, kind: str, table: pa.Table, meta: Mapping | None) -> dict:
    entry = {"path": os.fspath(path), "kind": kind, "sha256": sha256_file(path),
             "bytes": path.stat().st_size, "rows": table.num_rows,
             "columns": list(table.column_names)}
    for k, v in (meta or {}).items():
        if k in entry:
            raise ConfigError(f"manifest meta key '{k}' clashes with a reserved key")
        entry[k] = v
    return entry


#: Parquet schema-metadata key of a cell file's own record (:func:`write_metrics`).
CELL_META_KEY = b"oneocean"


def write_metrics(df: pd.DataFrame, path, *, meta: Mapping | None = None) -> dict:
    """Write per-episode metrics to Parquet atomically; return the manifest entry.

    Parameters
    ----------
    df : pandas.DataFrame
        One row per episode; the index is not written.
    path : path-like
        Output ``.parquet`` file.
    meta : mapping, optional
        JSON-able record (e.g. ``{"dynamics": "6dof", "vehicle": vehicle.spec, "dt_s": 1.0}``),
        copied into the entry and stored in the file itself (schema metadata
        :data:`CELL_META_KEY`, sorted-key JSON: the bytes stay deterministic), so a rollout file
        records its own configuration (:func:`read_metrics_meta`).

    Returns
    -------
    dict
        Manifest entry ``{path, kind, sha256, bytes, rows, columns, ...meta}`` with kind
        ``"episode_metrics"``.

    Raises
    ------
    ConfigError
        If a ``meta`` key clashes with a reserved entry key.
    """
    import json

    import pyarrow as pa

    path = Path(path)
    table = pa.Table.from_pandas(df, preserve_index=False)
    if meta:
        md = dict(table.schema.metadata or {})
        md[CELL_META_KEY] = json.dumps(meta, sort_keys=True, default=str).encode()
        table = table.replace_schema_metadata(md)
    _write_table(table, path)
    return _entry(path, "episode_metrics", table, meta)


def read_metrics_meta(path) -> dict:
    """The record :func:`write_metrics` stored in a cell file.

    Parameters
    ----------
    path : path-like
        A Parquet file written by :func:`write_metrics`.

    Returns
    -------
    dict
        The stored ``meta``; ``{}`` if none.
    """
    import json

    import pyarrow.parquet as pq

    md = pq.read_schema(path).metadata or {}
    raw = md.get(CELL_META_KEY)
    return json.loads(raw) if raw else {}
