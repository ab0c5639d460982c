"""Source readers: every provider's files → one canonical vocabulary (contracts.md §1).

Public API
----------
fetch_currents(cfg, out_path, cache_dir)
    Currents (and tides) for the configured region from ``sources.currents`` →
    one canonical NetCDF at ``out_path``.
fetch_bathymetry(cfg, out_path, cache_dir)
    Elevation for the configured region from ``sources.bathymetry`` → ``out_path``.
open_currents(path), open_bathymetry(path)
    Any canonical or provider file → validated canonical lazy dataset.
read_currents_file(path, variables=None), read_bathymetry_file(path)
    Provider file → canonical lazy dataset (no subsetting).
"""

from __future__ import annotations

import importlib
import os
from typing import Mapping, Sequence

import xarray as xr

from ..vocab import validate_choice
from .base import read, set_coord_attrs, to_json, validate, write_canonical

CURRENT_SOURCES: tuple[str, ...] = ("synthetic", "cmems", "files")
BATHYMETRY_SOURCES: tuple[str, ...] = ("synthetic", "gebco", "etopo", "files")


def read_currents_file(path: str | os.PathLike,
                       variables: Sequence[str] | None = None) -> xr.Dataset:
    """Read a provider (or canonical) currents file into the canonical vocabulary.

    Parameters
    ----------
    path : str or os.PathLike
        A NetCDF file with e.g. ``uo``/``vo`` (CMEMS), ``utide``/``vtide`` or canonical names.
    variables : sequence of str, optional
        Canonical variables to require (and keep), e.g. ``("u_tide", "v_tide")``; default
        ``u``, ``v`` plus ``u_tide``/``v_tide`` when present.

    Returns
    -------
    xarray.Dataset
        Dask-backed: ``u``, ``v`` (time, depth, latitude, longitude) float32 m s-1, NaN on
        land; ``u_tide``, ``v_tide`` (time, latitude, longitude) float32 m s-1.

    Raises
    ------
    DataError
        Missing/corrupt file, missing variable, swapped axes, unsupported units.
    """
    return read(path, "currents", variables)


def read_bathymetry_file(path: str | os.PathLike) -> xr.Dataset:
    """Read a provider (or canonical) bathymetry file into the canonical vocabulary.

    Parameters
    ----------
    path : str or os.PathLike
        A GEBCO NetCDF/GeoTIFF, an ETOPO NetCDF (``z``) or a canonical file.

    Returns
    -------
    xarray.Dataset
        Dask-backed: ``elevation`` (latitude, longitude) float32, m, positive up.

    Raises
    ------
    DataError
        Missing/corrupt file, missing variable, swapped axes, unsupported units.
    """
    return read(path, "bathymetry")


def open_currents(path: str | os.PathLike) -> xr.Dataset:
    """Open a canonical (or provider) currents file as a validated canonical lazy dataset.

    Parameters
    ----------
    path : str or os.PathLike
        A currents file (see :func:`read_currents_file`).

    Returns
    -------
    xarray.Dataset
        As :func:`read_currents_file`, checked by :func:`~oneocean.sources.base.validate`.

    Raises
    ------
    DataError
        The file cannot be read, or is not a canonical currents dataset.
    """
    return validate(read_currents_file(path), str(path), "currents")


def open_bathymetry(path: str | os.PathLike) -> xr.Dataset:
    """Open a canonical (or provider) bathymetry file as a validated canonical lazy dataset.

    Parameters
    ----------
    path : str or os.PathLike
        A bathymetry file (see :func:`read_bathymetry_file`).

    Returns
    -------
    xarray.Dataset
        As :func:`read_bathymetry_file`, checked by :func:`~oneocean.sources.base.validate`.

    Raises
    ------
    DataError
        The file cannot be read, or is not a canonical bathymetry dataset.
    """
    return validate(read_bathymetry_file(path), str(path), "bathymetry")


def fetch_currents(cfg: Mapping, out_path: str | os.PathLike,
                   cache_dir: str | os.PathLike) -> None:
    """Write the region's canonical currents file from ``cfg["sources"]["currents"]``.

    Parameters
    ----------
    cfg : Mapping
        The validated config (``region``, ``sources`` and the source kind's section).
    out_path : str or os.PathLike
        The canonical NetCDF to write (atomically; nothing is left on failure).
    cache_dir : str or os.PathLike
        Folder for downloads (remote sources); reruns reuse its files.

    Raises
    ------
    ConfigError
        An unknown ``sources.currents`` kind, or a required file setting is missing.
    DataError
        An input is missing, unreadable or does not cover the region.
    CredentialsError
        Copernicus Marine needs credentials that are not available.

    Notes
    -----
    Cut to ``region.bbox`` plus one source cell, the times bracketing ``region.time`` and
    the levels down to the first one deeper than ``region.max_depth_m``. With
    ``sources.tides`` the file also holds ``u_tide``/``v_tide``.
    """
    kind = validate_choice(cfg["sources"]["currents"], CURRENT_SOURCES, "sources.currents")
    if kind == "synthetic":
        ds = _synthetic(cfg, "currents")
    else:
        ds = importlib.import_module(f"{__name__}.{kind}").currents(cfg, cache_dir)
    write_canonical(ds, out_path, "currents")


def fetch_bathymetry(cfg: Mapping, out_path: str | os.PathLike,
                     cache_dir: str | os.PathLike) -> None:
    """Write the region's canonical bathymetry file from ``cfg["sources"]["bathymetry"]``.

    Parameters
    ----------
    cfg : Mapping
        The validated config (``region``, ``sources`` and the source kind's section).
    out_path : str or os.PathLike
        The canonical NetCDF to write (atomically; nothing is left on failure).
    cache_dir : str or os.PathLike
        Folder for downloads (remote GEBCO); reruns reuse its files.

    Raises
    ------
    ConfigError
        An unknown ``sources.bathymetry`` kind, or a required file setting is missing.
    DataError
        An input is missing, unreadable or does not cover the region.
    """
    kind = validate_choice(cfg["sources"]["bathymetry"], BATHYMETRY_SOURCES,
                           "sources.bathymetry")
    if kind == "synthetic":
        ds = _synthetic(cfg, "bathymetry")
    else:
        ds = importlib.import_module(f"{__name__}.{kind}").bathymetry(cfg, cache_dir)
    write_canonical(ds, out_path, "bathymetry")


def _synthetic(cfg: Mapping, what: str) -> xr.Dataset:
    """The embedded synthetic region (already canonical, built for the configured region)."""
    synthetic = importlib.import_module(f"{__name__}.synthetic")
    if what == "currents":
        ds = synthetic.make_currents(cfg)
        if not cfg["sources"]["tides"]:
            ds = ds.drop_vars(["u_tide", "v_tide"], errors="ignore")
    else:
        ds = synthetic.make_bathymetry(cfg)
    ds = set_coord_attrs(ds, "synthetic")  # e.g. pandas 3 makes datetime64[us] times
    ds.attrs["source"] = "synthetic"
    ds.attrs.setdefault("source_files", to_json([]))
    return ds


__all__ = [
    "fetch_bathymetry", "fetch_currents", "open_bathymetry", "open_currents",
    "read_bathymetry_file", "read_currents_file",
]
