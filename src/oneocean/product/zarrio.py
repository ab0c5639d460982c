"""Zarr stores for large products: deterministic, atomic writing, hashing and format dispatch.

A product is a NetCDF file (``.nc``) or a zarr store (``.zarr``, a directory); the suffix picks
the format everywhere (:func:`is_zarr`, :func:`open_product`). Stores are zarr format 2 with
consolidated metadata (``.zmetadata``), fixed chunks (one time step, as the NetCDF product) and a
fixed zstd compressor, and nothing time-of-writing in their attributes, so the same inputs give
the same bytes whichever dask scheduler computed them. They are written into a temporary
directory beside the target and renamed into place, so a failed write leaves no partial store.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Iterator

import numpy as np

from ..errors import DataError
from ..io import _free_bytes, _UMASK, disk_full_reason, sha256_file

if TYPE_CHECKING:  # xarray is imported where a product is opened, not by the engine
    import xarray as xr

__all__ = ["ZARR_SUFFIX", "PRODUCT_FORMATS", "EXPORT_FORMATS", "is_zarr", "product_filename",
           "export_filename", "zarr_encoding", "write_zarr", "write_zarr_atomic", "atomic_dir",
           "open_product", "store_sha256", "sha256_path", "path_bytes", "write_arrays_zarr",
           "read_arrays_zarr", "is_arrays_store", "arrays_content_hash"]

ZARR_SUFFIX = ".zarr"
#: Product formats (config ``product.format``) and their file suffixes.
PRODUCT_FORMATS = {"netcdf": ".nc", "zarr": ZARR_SUFFIX}
#: Export formats (config ``exports.format``) and their file suffixes.
EXPORT_FORMATS = {"npz": ".npz", "zarr": ZARR_SUFFIX}
_ZSTD_LEVEL = 3
_TIME_UNITS = "seconds since 1970-01-01 00:00:00"
#: Files a workflow engine may drop into a directory output; not part of the store's content.
_IGNORED = frozenset({".snakemake_timestamp"})
#: The group attribute of a store of named arrays (an export), :func:`write_arrays_zarr`.
_ARRAYS_ATTR = {"oneocean_store": "arrays"}


def is_zarr(path) -> bool:
    """Whether ``path`` names a zarr store (suffix ``.zarr``, trailing slash allowed).

    Parameters
    ----------
    path : str or os.PathLike
        A product or export path; only its name is looked at, it need not exist.

    Returns
    -------
    bool
        True when the name ends in ``.zarr``.
    """
    return os.fspath(path).rstrip("/\\").endswith(ZARR_SUFFIX)


def product_filename(fmt: str = "netcdf") -> str:
    """The product's file name for config ``product.format``.

    Parameters
    ----------
    fmt : str, default "netcdf"
        ``"netcdf"`` or ``"zarr"`` (the keys of :data:`PRODUCT_FORMATS`).

    Returns
    -------
    str
        ``product.nc`` or ``product.zarr``.

    Raises
    ------
    ConfigError
        ``fmt`` is not a product format.
    """
    from ..errors import ConfigError

    if fmt not in PRODUCT_FORMATS:
        raise ConfigError(f"product.format: Invalid value {fmt!r}. Valid options are "
                          f"({', '.join(PRODUCT_FORMATS)})")
    return "product" + PRODUCT_FORMATS[fmt]


def export_filename(kind: str, fmt: str = "npz") -> str:
    """An export's file name for config ``exports.format``.

    Parameters
    ----------
    kind : str
        The export: ``"grid"`` or ``"temporal"``.
    fmt : str, default "npz"
        ``"npz"`` or ``"zarr"`` (the keys of :data:`EXPORT_FORMATS`).

    Returns
    -------
    str
        ``<kind>.npz`` or ``<kind>.zarr``.

    Raises
    ------
    ConfigError
        ``fmt`` is not an export format.
    """
    from ..errors import ConfigError

    if fmt not in EXPORT_FORMATS:
        raise ConfigError(f"exports.format: Invalid value {fmt!r}. Valid options are "
                          f"({', '.join(EXPORT_FORMATS)})")
    return kind + EXPORT_FORMATS[fmt]


def zarr_encoding(ds: xr.Dataset, netcdf_enc: dict) -> dict:
    """Deterministic zarr encoding with the chunks and dtypes of the NetCDF encoding.

    Parameters
    ----------
    ds : xr.Dataset
        The product to write.
    netcdf_enc : dict
        :func:`oneocean.product.ncio.netcdf_encoding` of ``ds`` (its ``chunksizes`` and ``dtype``).

    Returns
    -------
    dict
        Per variable: ``dtype``, ``chunks`` (whole coordinates; one time step for data), a zstd
        compressor at a fixed level, NaN fill for floats and none for integers; time as float64
        seconds since 1970-01-01.
    """
    from numcodecs import Zstd

    enc: dict = {}
    for name, var in ds.variables.items():
        nc = netcdf_enc[name]
        chunks = nc.get("chunksizes") or tuple(var.shape)
        e = {"chunks": tuple(int(c) for c in chunks) if var.ndim else None,
             "compressors": [Zstd(level=_ZSTD_LEVEL)]}
        if np.issubdtype(var.dtype, np.datetime64):
            e.update(dtype="float64", units=_TIME_UNITS, calendar="proleptic_gregorian",
                     _FillValue=None)
        elif np.issubdtype(var.dtype, np.integer):
            e.update(dtype=str(var.dtype), _FillValue=None)
        elif name in ds.coords:
            e.update(dtype="float64", _FillValue=None)
        else:
            e.update(dtype=nc["dtype"], _FillValue=np.dtype(nc["dtype"]).type(np.nan))
        if e["chunks"] is None:
            del e["chunks"]
        enc[name] = e
    return enc


@contextlib.contextmanager
def atomic_dir(path, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield an empty temporary directory beside ``path``; rename it onto ``path`` on success.

    An existing ``path`` is replaced (moved aside, then removed after the rename). On any
    exception the temporary directory is removed, so no partial store is left behind.

    Parameters
    ----------
    path : str or os.PathLike
        The store to create or replace (a trailing slash is ignored); its parent directory is
        created if missing.
    suffix : str, default ".tmp"
        Ends the temporary directory's name (``.zarr`` lets :func:`open_product` recognise it).

    Yields
    ------
    pathlib.Path
        The temporary directory to write into.

    Raises
    ------
    DiskFullError
        The disk (or quota) is full (see :func:`~oneocean.io.disk_full_reason`); names ``path``.
    """
    from ..errors import DiskFullError

    path = Path(os.fspath(path).rstrip("/\\"))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent))
    except OSError as exc:
        what = disk_full_reason(exc, path.parent if path.parent.is_dir() else ".")
        if what:
            raise DiskFullError(path, _free_bytes(path.parent), what) from exc
        raise
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_UMASK)     # mkdtemp creates 0700
        old = None
        if path.exists() or path.is_symlink():
            old = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".old",
                                        dir=path.parent))
            os.replace(path, old / "store")
        os.replace(tmp, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException as exc:
        what = disk_full_reason(exc, path.parent) if isinstance(exc, Exception) else None
        free = _free_bytes(path.parent) if what else None
        shutil.rmtree(tmp, ignore_errors=True)
        if what:
            raise DiskFullError(path, free, what) from exc
        raise


def write_zarr(ds: xr.Dataset, store, encoding: dict) -> None:
    """Write ``ds`` (numpy- or dask-backed) into the (empty or absent) directory ``store``.

    Dask-backed variables are computed by the active dask scheduler (threads, or a
    ``dask.distributed`` client, whose workers then write the chunks: ``store``'s directory must
    be visible to them), one chunk per store object, so the bytes do not depend on scheduling.
    Metadata are consolidated (``.zmetadata``). Not atomic: see :func:`write_zarr_atomic`.

    Parameters
    ----------
    ds : xr.Dataset
        The dataset to write.
    store : str or os.PathLike
        The store's directory; its content is overwritten.
    encoding : dict
        Per-variable zarr encoding, :func:`zarr_encoding`.
    """
    ds.to_zarr(os.fspath(store), mode="w", consolidated=True, zarr_format=2,
               encoding=encoding, compute=True)


def write_zarr_atomic(ds: xr.Dataset, path, encoding: dict) -> None:
    """:func:`write_zarr` into a temporary directory beside ``path``, renamed onto it on success.

    No partial store is left on failure (:func:`atomic_dir`).

    Parameters
    ----------
    ds : xr.Dataset
        The dataset to write.
    path : str or os.PathLike
        The store to create or replace.
    encoding : dict
        Per-variable zarr encoding, :func:`zarr_encoding`.

    Raises
    ------
    DiskFullError
        The disk (or quota) is full.
    """
    with atomic_dir(path) as tmp:
        write_zarr(ds, tmp, encoding)


def write_arrays_zarr(path, arrays) -> None:
    """Write named arrays (an export's ``.npz`` content) as a zarr store, atomically.

    One zarr array per name with the array's dtype and shape (0-d and fixed-width unicode
    included), zarr format 2, consolidated metadata, a fixed zstd compressor, no fill value and
    no array attributes; arrays of 3 or more dimensions are chunked one step of their first axis at
    a time (the time axis of the exports), others are one chunk. The group's only attribute,
    ``oneocean_store: arrays``, tells it from a product (:func:`is_arrays_store`). The bytes
    depend only on the arrays. :func:`read_arrays_zarr` gives back the same mapping.

    Parameters
    ----------
    path : str or os.PathLike
        The store to create or replace.
    arrays : Mapping[str, array_like]
        The arrays by name; dtypes of kind bool, integer, float, complex, datetime, timedelta
        or fixed-width unicode.

    Raises
    ------
    TypeError
        An array has another dtype (e.g. object).
    DiskFullError
        The disk (or quota) is full.
    """
    import zarr
    from numcodecs import Zstd

    with atomic_dir(path, suffix=ZARR_SUFFIX) as tmp:
        group = zarr.open_group(store=os.fspath(tmp), mode="w", zarr_format=2)
        group.attrs.update(_ARRAYS_ATTR)
        for name in sorted(arrays):
            a = np.asarray(arrays[name])           # 0-d stays 0-d
            if a.dtype.kind not in "biufcMmU":
                raise TypeError(f"{path}: array {name!r} has dtype {a.dtype}, not storable")
            chunks = (1,) + a.shape[1:] if a.ndim >= 3 else a.shape
            z = group.create_array(name, shape=a.shape, dtype=a.dtype,
                                   chunks=tuple(max(int(c), 1) for c in chunks),
                                   compressors=Zstd(level=_ZSTD_LEVEL), fill_value=None)
            z[...] = a
        zarr.consolidate_metadata(os.fspath(tmp), zarr_format=2)


def is_arrays_store(path) -> bool:
    """Whether ``path`` is a zarr store written by :func:`write_arrays_zarr`.

    Parameters
    ----------
    path : str or os.PathLike
        A store (or any path).

    Returns
    -------
    bool
        True when the store's ``.zattrs`` has ``oneocean_store: arrays``; False when it does
        not, or cannot be read.
    """
    import json

    attrs = Path(os.fspath(path).rstrip("/\\")) / ".zattrs"
    try:
        return json.loads(attrs.read_text()).get("oneocean_store") == "arrays"
    except (OSError, ValueError, AttributeError):
        return False


def arrays_content_hash(path) -> str:
    """sha256 of the decoded arrays of a :func:`write_arrays_zarr` store.

    Parameters
    ----------
    path : str or os.PathLike
        The store.

    Returns
    -------
    str
        Hex sha256 over the names, dtypes, shapes and values, in name order
        (:func:`~oneocean.io.array_digest`).

    Raises
    ------
    DataError
        The store is missing or unreadable.
    """
    from ..io import array_digest

    h = hashlib.sha256()
    for name, arr in read_arrays_zarr(path).items():
        array_digest(h, name, arr)
    return h.hexdigest()


def read_arrays_zarr(path, what: str = "export") -> dict:
    """Every array of a store written by :func:`write_arrays_zarr`, read into memory.

    Parameters
    ----------
    path : str or os.PathLike
        The store.
    what : str, default "export"
        What the store is, for the error message.

    Returns
    -------
    dict of str to numpy.ndarray
        ``{name: ndarray}`` in name order, 0-d arrays as 0-d ndarrays.

    Raises
    ------
    DataError
        The store is missing or unreadable (one line, naming it as ``what``).
    """
    import zarr


    root = Path(os.fspath(path).rstrip("/\\"))
    if not root.is_dir():
        raise DataError(f"{root}: {what} not found")
    try:
        group = zarr.open_consolidated(os.fspath(root), mode="r", zarr_format=2)
        return {name: np.asarray(group[name][...]) for name in sorted(group.array_keys())}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        reason = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise DataError(f"{root}: not a readable zarr {what} ({reason})") from None


def open_product(path, **kwargs) -> xr.Dataset:
    """Open a product (NetCDF file or zarr store, by suffix) lazily with xarray.

    A zarr store is opened with its consolidated metadata (``cache`` is dropped for it).

    Parameters
    ----------
    path : str or os.PathLike
        The product: ``.zarr`` for a zarr store, a NetCDF file otherwise.
    **kwargs
        Passed to :func:`xarray.open_dataset` (e.g. ``decode_times``, ``cache``).

    Returns
    -------
    xr.Dataset
        The lazily opened product.
    """
    import xarray as xr

    if is_zarr(path):
        kwargs.pop("cache", None)
        return xr.open_dataset(path, engine="zarr", consolidated=True, **kwargs)
    return xr.open_dataset(path, **kwargs)


def _store_files(root: Path) -> list:
    files = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames.sort()
        for f in filenames:
            if f not in _IGNORED:
                full = Path(dirpath) / f
                files.append((full.relative_to(root).as_posix(), full))
    return sorted(files)


def store_sha256(path) -> str:
    """Hex sha256 of a directory store over its files in sorted relative-path order.

    Each file contributes its relative path, size and the sha256 of its bytes
    (``.snakemake_timestamp`` is left out).

    Parameters
    ----------
    path : str or os.PathLike
        The store's directory.

    Returns
    -------
    str
        The hex digest.

    Raises
    ------
    FileNotFoundError
        ``path`` is not a directory.
    """
    root = Path(path)
    if not root.is_dir():
        raise FileNotFoundError(f"{path}: not a directory")
    h = hashlib.sha256()
    for rel, full in _store_files(root):
        h.update(f"{rel}\n{full.stat().st_size}\n".encode())
        h.update(bytes.fromhex(sha256_file(full)))
    return h.hexdigest()


def sha256_path(path) -> str:
    """sha256 of a file's bytes, or :func:`store_sha256` of a zarr store (a directory).

    Parameters
    ----------
    path : str or os.PathLike
        A file, or a directory whose name ends in ``.zarr``.

    Returns
    -------
    str
        The hex digest.
    """
    return store_sha256(path) if Path(path).is_dir() and is_zarr(path) else sha256_file(path)


def path_bytes(path) -> int:
    """Size of a file, or the total size of a store's files.

    Parameters
    ----------
    path : str or os.PathLike
        A file or a directory store (``.snakemake_timestamp`` files are not counted).

    Returns
    -------
    int
        The size in bytes.
    """
    p = Path(path)
    if p.is_dir():
        return int(sum(full.stat().st_size for _, full in _store_files(p)))
    return int(p.stat().st_size)


def read_npz(path: str | os.PathLike, what: str) -> dict:
    """Every array of an ``.npz`` file (no pickles) or an arrays zarr store, read into memory.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.npz`` file, or a store written by :func:`write_arrays_zarr` (a
        path ending in ``.zarr``).
    what : str
        What the file is, for the error message.

    Returns
    -------
    dict of str to numpy.ndarray
        The arrays by name.

    Raises
    ------
    DataError
        The file is missing or unreadable (one line, naming it as ``what``).
    """
    if is_zarr(path):
        return read_arrays_zarr(path, what)
    path = Path(os.fspath(path))
    if not path.is_file():
        raise DataError(f"{path}: {what} not found")
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:  # zip errors are ValueError subclasses / OSError
        raise DataError(f"{path}: not a readable .npz {what} ({exc})") from exc
