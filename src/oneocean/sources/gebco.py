"""Source kind ``gebco``: GEBCO bathymetry from a local file or a remote ERDDAP/OPeNDAP URL.

Local files are the GEBCO download app's NetCDF (NETCDF3, dims ``lat``/``lon``, ``elevation``
int16, m positive up) or GeoTIFF (georeferenced by ``ModelPixelScale``/``ModelTiepoint``).
A remote URL is opened with xarray's netCDF4 engine and only the bbox is transferred; the
subset is cached in ``cache_dir`` under a hash of the request, so reruns stay offline.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping

import xarray as xr

from ..errors import ConfigError
from .base import cached_download, file_records, read, to_json, write_canonical


def open_remote(url: str) -> xr.Dataset:
    """Open a remote (OPeNDAP) dataset lazily; the network call tests patch.

    Parameters
    ----------
    url : str
        ERDDAP griddap or THREDDS OPeNDAP endpoint of a GEBCO grid.

    Returns
    -------
    xarray.Dataset
        Lazily indexed: only the slices used later are transferred.
    """
    return xr.open_dataset(url, engine="netcdf4", chunks=None, cache=False)


def build_request(cfg: Mapping) -> dict:
    """What defines a remote GEBCO subset: the URL and the bbox.

    Parameters
    ----------
    cfg : Mapping
        The validated config (``gebco.url``, ``region.bbox``).

    Returns
    -------
    dict
        ``url``, ``variables`` (``["elevation"]``) and ``west``, ``east``, ``south``,
        ``north`` (float, degrees); its hash names the cached subset.
    """
    bbox = cfg["region"]["bbox"]
    return {"url": str(cfg["gebco"]["url"]), "variables": ["elevation"],
            **{k: float(bbox[k]) for k in ("west", "east", "south", "north")}}


def _download_subset(request: Mapping, bbox: Mapping, part: Path) -> None:
    url = request["url"]
    ds = read(open_remote(url), "bathymetry", name=url, bbox=bbox)
    ds.attrs = {"source": "gebco", "source_files": to_json([]), "request": to_json(request)}
    write_canonical(ds, part, "bathymetry")


def bathymetry(cfg: Mapping, cache_dir: str | os.PathLike) -> xr.Dataset:
    """Canonical ``elevation`` (m, positive up) from ``gebco.path`` or ``gebco.url``.

    ``gebco.path`` wins when both are set; a URL's subset is downloaded once into
    ``cache_dir`` (``gebco.retries`` attempts, ``gebco.retry_wait_s`` apart).

    Parameters
    ----------
    cfg : Mapping
        The validated config (``gebco``, ``region.bbox``).
    cache_dir : str or os.PathLike
        Folder of completed downloads.

    Returns
    -------
    xarray.Dataset
        Canonical, dask-backed, cut to the bbox; attrs ``source="gebco"``, ``source_files``
        and, for a URL, ``request`` (JSON); the recorded file of a remote subset is its cached
        copy.

    Raises
    ------
    ConfigError
        Neither ``gebco.path`` nor ``gebco.url`` is set.
    DataError
        The file is unreadable or does not cover the bbox, or the download failed.
    """
    g = cfg["gebco"]
    bbox = cfg["region"]["bbox"]
    if g.get("path"):
        path = str(g["path"])
        ds = read(path, "bathymetry", bbox=bbox)
        ds.attrs.update(source="gebco", source_files=to_json(file_records([path])))
        return ds
    if g.get("url"):
        request = build_request(cfg)
        path = cached_download(
            cache_dir, "gebco", request, lambda part: _download_subset(request, bbox, part),
            retries=int(g.get("retries", 3)), retry_wait_s=float(g.get("retry_wait_s", 5.0)),
            label=f"GEBCO {request['url']}")
        ds = read(path, "bathymetry", bbox=bbox)
        ds.attrs.update(source="gebco", source_files=to_json(file_records([path])),
                        request=to_json(request))
        return ds
    raise ConfigError("gebco.path / gebco.url: one of them must be set for sources.bathymetry "
                      "'gebco'")
