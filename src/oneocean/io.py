"""Atomic, deterministic file I/O and hashing shared by every stage."""

from __future__ import annotations

import contextlib
import errno
import hashlib
import io
import json
import os
import shutil
import tempfile
import zipfile
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np

_CHUNK = 1 << 20
_UMASK = os.umask(0)
os.umask(_UMASK)


def read_yaml_mapping(path: str | os.PathLike, what: str) -> dict:
    """Read a YAML file whose top level is a mapping.

    Parameters
    ----------
    path : str or os.PathLike
        The YAML file.
    what : str
        Names the file in the errors, e.g. ``"task table"``.

    Returns
    -------
    dict
        The file's top-level mapping.

    Raises
    ------
    ConfigError
        The file is unreadable, not valid YAML, or its top level is not a mapping (one line,
        naming the file).
    """
    import yaml

    from .errors import ConfigError

    try:
        doc = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the {what} ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: the {what}'s top level must be a mapping")
    return doc


def sha256_file(path: str | os.PathLike) -> str:
    """Hex sha256 of a file's bytes, read in 1 MiB chunks.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    str
        The hex digest.
    """
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(_CHUNK), b""):
            h.update(block)
    return h.hexdigest()


#: Free bytes on a filesystem below which a failed write there is taken for a full disk:
#: HDF5 (hence netCDF4) reports a full disk as "NetCDF: HDF error", with no errno.
DISK_FULL_BYTES = 4 * 1024 * 1024

_FULL_ERRNOS = {errno.ENOSPC: "the disk is full", errno.EDQUOT: "the disk quota is exceeded"}


def _free_bytes(directory: Path) -> int | None:
    try:
        return int(shutil.disk_usage(directory).free)
    except OSError:
        return None


def disk_full_reason(exc: BaseException, directory: str | os.PathLike) -> str | None:
    """Why writing into ``directory`` failed with ``exc`` if the disk (or quota) is full.

    A full disk is an ``ENOSPC``/``EDQUOT`` errno anywhere in the exception's chain, "No space
    left on device" in a message of the chain, or an I/O error (``OSError``/``RuntimeError``,
    e.g. netCDF4's HDF error) while less than :data:`DISK_FULL_BYTES` are free there.

    Parameters
    ----------
    exc : BaseException
        The exception the write raised.
    directory : str or os.PathLike
        The directory written into (its free space is measured).

    Returns
    -------
    str or None
        ``"the disk is full"`` or ``"the disk quota is exceeded"``; None when the failure is
        not a full disk.
    """
    seen, e = set(), exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, OSError) and e.errno in _FULL_ERRNOS:
            return _FULL_ERRNOS[e.errno]
        if "No space left on device" in str(e):
            return _FULL_ERRNOS[errno.ENOSPC]
        e = e.__cause__ or e.__context__
    if isinstance(exc, (OSError, RuntimeError)):
        free = _free_bytes(Path(directory))
        if free is not None and free < DISK_FULL_BYTES:
            return _FULL_ERRNOS[errno.ENOSPC]
    return None


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` only on success.

    On any exception the temporary file is removed, so no partial artifact is left behind. The
    temporary file gets the usual umask permissions before the rename.

    Parameters
    ----------
    path : str or os.PathLike
        The file to create or replace; its parent directory is created if missing.
    suffix : str, optional
        Ends the temporary file's name; default ``path``'s suffix, or ``.tmp`` if it has none.

    Yields
    ------
    pathlib.Path
        The temporary file (created empty) to write.

    Raises
    ------
    DiskFullError
        The disk (or quota) is full (see :func:`disk_full_reason`); one line naming ``path``
        and the free space left.
    """
    from .errors import DiskFullError

    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.",
                                   suffix=suffix or path.suffix or ".tmp", dir=path.parent)
    except OSError as exc:
        what = disk_full_reason(exc, path.parent if path.parent.is_dir() else ".")
        if what:
            raise DiskFullError(path, _free_bytes(path.parent), what) from exc
        raise
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        if tmp.exists():  # mkstemp creates 0600; give the file the usual umask permissions
            os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    except DiskFullError as exc:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        if Path(exc.path) == tmp:   # a nested atomic writer of our temporary file: name ours
            raise DiskFullError(path, exc.free, exc.what) from exc.__cause__
        raise
    except BaseException as exc:
        # measured before the partial file is removed: the free space when the write failed
        what = disk_full_reason(exc, path.parent) if isinstance(exc, Exception) else None
        free = _free_bytes(path.parent) if what else None
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        if what:
            raise DiskFullError(path, free, what) from exc
        raise


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (:func:`atomic_path`).

    Parameters
    ----------
    path : str or os.PathLike
        The file to create or replace.
    data : bytes
        The file's content.
    """
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` as UTF-8, atomically (:func:`atomic_path`).

    Parameters
    ----------
    path : str or os.PathLike
        The file to create or replace.
    text : str
        The file's content.
    """
    write_bytes_atomic(path, text.encode("utf-8"))


def canonical_json(obj) -> str:
    """JSON with sorted keys and fixed separators: equal objects give equal bytes.

    Parameters
    ----------
    obj : object
        JSON-serialisable data; numpy scalars and arrays and :class:`pathlib.Path` are
        converted (to numbers, lists and strings).

    Returns
    -------
    str
        The JSON text, indented by 2, ending in a newline.

    Raises
    ------
    TypeError
        ``obj`` holds a value JSON cannot represent.
    """
    return json.dumps(obj, sort_keys=True, indent=2, default=_json_default) + "\n"


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def write_json_atomic(path: str | os.PathLike, obj) -> None:
    """Write ``obj`` as :func:`canonical_json` to ``path``, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The file to create or replace.
    obj : object
        JSON-serialisable data (see :func:`canonical_json`).
    """
    write_text_atomic(path, canonical_json(obj))


def config_hash(obj) -> str:
    """sha256 of the canonical JSON of a config snapshot.

    Parameters
    ----------
    obj : object
        The config (or any JSON-serialisable data, see :func:`canonical_json`).

    Returns
    -------
    str
        Hex sha256 of :func:`canonical_json` of ``obj``.
    """
    return hashlib.sha256(canonical_json(obj).encode()).hexdigest()


_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


def write_npz_atomic(path: str | os.PathLike, arrays: Mapping[str, np.ndarray]) -> None:
    """Write an ``.npz`` readable by :func:`numpy.load` whose bytes depend only on the arrays.

    ``numpy.savez`` stamps the current time into every zip member; here members are written
    in sorted order with a fixed timestamp, uncompressed, so identical inputs give identical bytes.

    Parameters
    ----------
    path : str or os.PathLike
        The file to create or replace.
    arrays : Mapping[str, numpy.ndarray]
        The arrays by name (member ``<name>.npy``); object arrays are refused (no pickles).
    """
    with atomic_path(path, suffix=".npz") as tmp:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as zf:
            for name in sorted(arrays):
                buf = io.BytesIO()
                np.lib.format.write_array(buf, np.asanyarray(arrays[name]), allow_pickle=False)
                info = zipfile.ZipInfo(f"{name}.npy", date_time=_ZIP_EPOCH)
                info.external_attr = 0o644 << 16
                zf.writestr(info, buf.getvalue())


def array_digest(h: "hashlib._Hash", name: str, arr: np.ndarray) -> None:
    """Feed an array's name, dtype, shape and values into the hash ``h``.

    Parameters
    ----------
    h : hashlib hash object
        The running hash, updated in place.
    name : str
        The array's name.
    arr : array_like
        The array; string and object arrays are hashed by their values' ``str`` joined with
        ``\\x1f``, others by their C-contiguous bytes.
    """
    arr = np.ascontiguousarray(np.asarray(arr))
    h.update(name.encode())
    h.update(str(arr.dtype).encode())
    h.update(repr(arr.shape).encode())
    if arr.dtype.kind in "OUS":
        h.update("\x1f".join(map(str, arr.ravel().tolist())).encode())
    else:
        h.update(arr.tobytes())


def dataset_content_hash(ds) -> str:
    """Stable sha256 of an xarray Dataset's decoded content (variables, coords, attributes).

    Used for formats (NetCDF/HDF5) whose bytes may embed write-time metadata. Variables are
    streamed chunk by chunk along their first dimension so large products never load whole.

    Parameters
    ----------
    ds : xr.Dataset
        The dataset (lazily opened is fine).

    Returns
    -------
    str
        The hex digest.
    """
    h = hashlib.sha256()
    h.update(canonical_json({k: _attr(v) for k, v in ds.attrs.items()}).encode())
    for name in sorted(map(str, ds.variables)):
        var = ds.variables[name]
        h.update(canonical_json({"name": name, "dims": list(var.dims),
                                 "attrs": {k: _attr(v) for k, v in var.attrs.items()}}).encode())
        if var.ndim == 0 or var.shape[0] == 0:
            array_digest(h, name, var.values)
            continue
        for i in range(var.shape[0]):
            array_digest(h, f"{name}[{i}]", var[i].values)
    return h.hexdigest()


def _attr(v):
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.integer, np.floating)):
        return v.item()
    return v
