"""A full disk while an artifact is written: one line naming the file, that the disk is full
and the free space left; no partial or temporary file remains."""

import errno
import shutil
from collections import namedtuple
from pathlib import Path

import dask
import numpy as np
import pandas as pd
import pytest
import xarray as xr

from oneocean import io as oio
from oneocean.engine.recording import write_metrics
from oneocean.errors import DiskFullError, OneOceanError
from oneocean.io import atomic_path, write_json_atomic, write_npz_atomic
from oneocean.product.ncio import netcdf_encoding, write_netcdf_atomic

_Usage = namedtuple("_Usage", "total used free")


def _free(monkeypatch, free):
    """Make ``shutil.disk_usage`` report ``free`` bytes."""
    monkeypatch.setattr(shutil, "disk_usage", lambda p: _Usage(10**9, 10**9 - free, free))


def _enospc(*_a, **_k):
    raise OSError(errno.ENOSPC, "No space left on device")


def _dataset():
    return xr.Dataset(
        {"u": (("time", "latitude", "longitude"), np.ones((3, 5, 6)))},
        coords={"time": np.arange(3.0), "latitude": np.arange(5.0),
                "longitude": np.arange(6.0)})


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_enospc_while_writing_json(tmp_path, monkeypatch):
    out = tmp_path / "results" / "meta.json"
    real_write = Path.write_bytes

    def half_then_full(self, data):   # half the bytes reach the disk, then ENOSPC
        real_write(self, data[: len(data) // 2])
        _enospc()

    monkeypatch.setattr(Path, "write_bytes", half_then_full)
    _free(monkeypatch, 4096)
    with pytest.raises(DiskFullError) as err:
        write_json_atomic(out, {"a": list(range(100))})
    msg = str(err.value)
    assert msg == (f"{out}: cannot write: the disk is full (4096 bytes = 0.0 MB free); "
                   "no partial file was left")
    assert isinstance(err.value, OneOceanError) and "\n" not in msg
    assert err.value.path == out and err.value.free == 4096
    assert _leftovers(out.parent) == []


def test_netcdf_hdf_error_on_a_full_disk_names_the_file(tmp_path, monkeypatch):
    out = tmp_path / "product.nc"

    def hdf_error(*_a, **_k):         # what netCDF4 raises when HDF5 hits ENOSPC
        raise RuntimeError("NetCDF: HDF error")

    monkeypatch.setattr(dask, "compute", hdf_error)
    _free(monkeypatch, 0)
    ds = _dataset()
    with pytest.raises(DiskFullError, match=r"product\.nc: cannot write: the disk is full "
                       r"\(0 bytes = 0\.0 MB free\); no partial file was left$") as err:
        write_netcdf_atomic(ds, out, netcdf_encoding(ds))
    assert isinstance(err.value.__cause__, RuntimeError)
    assert _leftovers(tmp_path) == []


def test_netcdf_hdf_error_with_room_left_is_not_called_disk_full(tmp_path, monkeypatch):
    def hdf_error(*_a, **_k):
        raise RuntimeError("NetCDF: HDF error")

    monkeypatch.setattr(dask, "compute", hdf_error)
    _free(monkeypatch, 50 * 10**9)
    ds = _dataset()
    with pytest.raises(RuntimeError, match="HDF error"):
        write_netcdf_atomic(ds, tmp_path / "product.nc", netcdf_encoding(ds))
    assert _leftovers(tmp_path) == []


def test_nested_atomic_writer_names_the_final_artifact(tmp_path, monkeypatch):
    # the product stage writes its NetCDF into its own temporary path (atomic_path inside
    # atomic_path): the error names the product, not the temporary file
    monkeypatch.setattr(dask, "compute", _enospc)
    _free(monkeypatch, 2 * 10**6)
    out = tmp_path / "product" / "product.nc"
    ds = _dataset()
    with pytest.raises(DiskFullError) as err:
        with atomic_path(out, suffix=".nc") as tmp:
            write_netcdf_atomic(ds, tmp, netcdf_encoding(ds))
    assert str(err.value).startswith(f"{out}: cannot write: the disk is full (2000000 bytes "
                                     "= 2.0 MB free)")
    assert _leftovers(out.parent) == []


def test_parquet_and_npz_writers(tmp_path, monkeypatch):
    import pyarrow.parquet as pq

    _free(monkeypatch, 10**5)
    monkeypatch.setattr(pq, "write_table", _enospc)
    with pytest.raises(DiskFullError, match=r"cell\.parquet: cannot write: the disk is full "
                       r"\(100000 bytes = 0\.1 MB free\)"):
        write_metrics(pd.DataFrame({"episode": [0, 1]}), tmp_path / "cell.parquet")
    monkeypatch.setattr(oio.zipfile.ZipFile, "writestr", _enospc)
    with pytest.raises(DiskFullError, match=r"grid\.npz: cannot write: the disk is full"):
        write_npz_atomic(tmp_path / "grid.npz", {"a": np.arange(3)})
    assert _leftovers(tmp_path) == []


def test_no_room_for_the_temporary_file_and_quota(tmp_path, monkeypatch):
    monkeypatch.setattr(oio.tempfile, "mkstemp", _enospc)
    _free(monkeypatch, 0)
    with pytest.raises(DiskFullError, match=r"a\.json: cannot write: the disk is full"):
        write_json_atomic(tmp_path / "a.json", {})
    monkeypatch.undo()

    def quota(self, data):
        raise OSError(errno.EDQUOT, "Disk quota exceeded")

    monkeypatch.setattr(Path, "write_bytes", quota)
    with pytest.raises(DiskFullError, match=r"b\.json: cannot write: the disk quota is "
                       r"exceeded \(\d+ bytes = [\d.]+ MB free\)"):
        write_json_atomic(tmp_path / "b.json", {})
    assert _leftovers(tmp_path) == []


def test_other_failures_pass_through_unchanged(tmp_path, monkeypatch):
    _free(monkeypatch, 0)   # even on a full disk, a non-I/O error is not a disk-full error
    with pytest.raises(ValueError, match="boom"):
        with atomic_path(tmp_path / "x.json") as tmp:
            tmp.write_text("partial")
            raise ValueError("boom")
    monkeypatch.undo()
    with pytest.raises(PermissionError):
        with atomic_path(tmp_path / "y.json"):
            raise PermissionError(errno.EACCES, "Permission denied")
    assert _leftovers(tmp_path) == []
