"""Source kind ``etopo``: NOAA ETOPO 2022 NetCDF (variable ``z``, m positive up)."""

from __future__ import annotations

import os
from typing import Mapping

import xarray as xr

from ..errors import ConfigError
from .base import file_records, read, to_json


def bathymetry(cfg: Mapping, cache_dir: str | os.PathLike | None = None) -> xr.Dataset:
    """Canonical ``elevation`` (m, positive up) from ``etopo.path``, cut to the region bbox.

    Parameters
    ----------
    cfg : Mapping
        The validated config (``etopo.path``, ``region.bbox``).
    cache_dir : str or os.PathLike, optional
        Unused (the source kinds share one signature).

    Returns
    -------
    xarray.Dataset
        Canonical, dask-backed; attrs ``source="etopo"`` and ``source_files``.

    Raises
    ------
    ConfigError
        ``etopo.path`` is not set.
    DataError
        The file is missing, unreadable or does not cover the bbox.
    """
    path = cfg["etopo"].get("path")
    if not path:
        raise ConfigError("etopo.path: required for sources.bathymetry 'etopo'")
    ds = read(str(path), "bathymetry", bbox=cfg["region"]["bbox"])
    ds.attrs.update(source="etopo", source_files=to_json(file_records([path])))
    return ds
