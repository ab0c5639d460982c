"""Deterministic, streaming NetCDF4 writing shared by every stage that writes NetCDF.

HDF5's on-disk layout depends on the order chunks are written; writing from dask threads makes
the bytes differ between runs. These helpers write one time block at a time in a fixed order.
"""

from __future__ import annotations

import contextlib

import dask
import numpy as np
import xarray as xr

from ..io import atomic_path

_TIME_UNITS = "seconds since 1970-01-01 00:00:00"
_MAX_CHUNK_ELEMENTS = 4 * 1024 * 1024      # ~16 MB float32 per HDF5 chunk
_CHUNK_CACHE_BYTES = 4 * 1024 * 1024       # per-variable HDF5 chunk cache while streaming


@contextlib.contextmanager
def netcdf_chunk_cache(size_bytes: int = _CHUNK_CACHE_BYTES):
    """Set netCDF4's default per-variable HDF5 chunk cache for files opened inside the block.

    The library default (64 MiB per variable) fills up when a product is streamed one time step
    at a time and adds ~0.5 GB of resident memory across inputs and outputs; every stage here
    reads or writes each chunk once, so a small cache costs nothing. Restored on exit.

    Parameters
    ----------
    size_bytes : int, default 4 MiB
        The cache size per variable, bytes (the number of slots and the preemption are kept).

    Yields
    ------
    None
    """
    import netCDF4

    old = netCDF4.get_chunk_cache()
    netCDF4.set_chunk_cache(int(size_bytes), old[1], old[2])
    try:
        yield
    finally:
        netCDF4.set_chunk_cache(*old)


# --- grid and interpolation (pure functions) ------------------------------------------------


def netcdf_encoding(ds: xr.Dataset, zlib: bool = True, complevel: int = 1) -> dict:
    """Deterministic NetCDF4 encoding for :func:`write_netcdf_atomic`.

    Floating data variables become float32 with a NaN fill, integer ones keep their dtype with no
    fill, coordinates float64 with no fill, time float64 seconds since 1970; data chunks hold one
    time step (capped at ~16 MB by splitting latitude).

    Parameters
    ----------
    ds : xr.Dataset
        The dataset to write.
    zlib : bool, default True
        Compress data variables with zlib (and the shuffle filter); coordinates never are.
    complevel : int, default 1
        The zlib level, 1 to 9.

    Returns
    -------
    dict
        Per variable: ``dtype``, ``fill_value`` (False: none), ``zlib``, and for data variables
        ``complevel``, ``shuffle`` and ``chunksizes`` (None for scalars and coordinates).
    """
    enc: dict = {}
    for name, var in ds.variables.items():
        if name in ds.coords:
            enc[name] = {"dtype": "float64", "fill_value": False, "zlib": False,
                         "chunksizes": None}
            continue
        chunks = list(var.shape)
        if "time" in var.dims:
            chunks[var.dims.index("time")] = 1
        if "latitude" in var.dims:
            j = var.dims.index("latitude")
            per_row = max(1, int(np.prod(chunks)) // max(chunks[j], 1))
            chunks[j] = max(1, min(chunks[j], _MAX_CHUNK_ELEMENTS // per_row))
        integer = np.issubdtype(var.dtype, np.integer)
        enc[name] = {"dtype": str(var.dtype) if integer else "float32",
                     "fill_value": False if integer else np.float32(np.nan),
                     "zlib": bool(zlib), "complevel": int(complevel), "shuffle": bool(zlib),
                     "chunksizes": tuple(max(c, 1) for c in chunks) if var.ndim else None}
    return enc


def _nc_values(var: xr.Variable) -> np.ndarray:
    """Values to store: datetime64 as float64 seconds since 1970-01-01."""
    vals = np.asarray(var.values)
    if np.issubdtype(vals.dtype, np.datetime64):
        ns = vals.astype("datetime64[ns]").astype(np.int64)
        return ns.astype(np.float64) * 1e-9
    return vals


def write_netcdf_atomic(ds: xr.Dataset, path, encoding: dict) -> None:
    """Write ``ds`` (numpy- or dask-backed) to NetCDF4 deterministically and atomically.

    Variables are defined in the dataset's order; time-dependent variables are computed and
    written one dask time chunk at a time (dask threads within a chunk, a fixed write order
    across chunks), so memory stays at ~one time chunk of every variable and the HDF5 layout,
    hence the file's bytes, do not depend on thread scheduling. ``datetime64`` coordinates are
    written as float64 seconds since 1970-01-01. Nothing time-of-writing is recorded.

    Parameters
    ----------
    ds : xr.Dataset
        The dataset to write.
    path : str or os.PathLike
        The NetCDF file to create or replace (via :func:`~oneocean.io.atomic_path`).
    encoding : dict
        Per-variable encoding, :func:`netcdf_encoding`.

    Raises
    ------
    DiskFullError
        The disk (or quota) is full.
    """
    import netCDF4

    names = list(ds.coords) + list(ds.data_vars)
    with atomic_path(path, suffix=".nc") as tmp:
        with netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
            for dim, size in ds.sizes.items():
                nc.createDimension(dim, size)
            stepped = []
            for name in names:
                var, enc = ds[name].variable, encoding[name]
                kw = {"zlib": enc["zlib"], "fill_value": enc["fill_value"]}
                if enc.get("zlib"):
                    kw.update(complevel=enc["complevel"], shuffle=enc["shuffle"])
                if enc.get("chunksizes"):
                    kw["chunksizes"] = enc["chunksizes"]
                ncv = nc.createVariable(name, np.dtype(enc["dtype"]), var.dims, **kw)
                if enc.get("chunksizes"):      # whole chunks are written once: no big cache
                    ncv.set_var_chunk_cache(size=_CHUNK_CACHE_BYTES)
                attrs = dict(var.attrs)
                if np.issubdtype(var.dtype, np.datetime64):
                    attrs.update(units=_TIME_UNITS, calendar="proleptic_gregorian")
                ncv.setncatts(attrs)
                if var.dims[:1] == ("time",) and name not in ds.coords:
                    stepped.append(name)
                else:
                    ncv[...] = _nc_values(var).astype(enc["dtype"], copy=False)
            nc.setncatts(dict(ds.attrs))
            for k0, k1 in _time_blocks(ds, stepped):
                vals = dask.compute(*[ds[n].data[k0:k1] for n in stepped])
                for n, val in zip(stepped, vals):
                    nc[n][k0:k1] = np.asarray(val).astype(encoding[n]["dtype"], copy=False)


def _time_blocks(ds: xr.Dataset, names: list) -> list:
    """[(k0, k1)] slabs along time: the dask time chunks of the first variable (else steps)."""
    if not names:
        return []
    data = ds[names[0]].data
    sizes = data.chunks[0] if hasattr(data, "chunks") and data.chunks else (1,) * data.shape[0]
    edges = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


# --- inputs --------------------------------------------------------------------------------
