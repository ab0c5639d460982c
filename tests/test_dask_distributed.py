"""The product computed on a dask.distributed cluster (config ``product.scheduler``) is
byte-identical to the local threads build, NetCDF and zarr."""

from __future__ import annotations

import json
import sys

import pytest

from oneocean.errors import ConfigError
from oneocean.io import sha256_file
from oneocean.product.build import build_product, compute_scheduler
from oneocean.sources import fetch_bathymetry, fetch_currents
from oneocean.product.zarrio import open_product, store_sha256

from test_zarr_product import small_config

pytestmark = pytest.mark.slow

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    root = tmp_path_factory.mktemp("distributed")
    cfg = small_config()
    cur, bat = root / "currents.nc", root / "bathymetry.nc"
    fetch_currents(cfg, cur, root / "cache")
    fetch_bathymetry(cfg, bat, root / "cache")
    for name in ("product.nc", "product.zarr"):
        build_product(cur, bat, cfg, "tiny", root / "threads" / name,
                      root / "threads" / f"{name}.json")
    return {"root": root, "cfg": cfg, "currents": cur, "bathymetry": bat}


def _with_scheduler(cfg: dict, address: str | None) -> dict:
    cfg = json.loads(json.dumps(cfg))
    cfg["product"] = {"format": "netcdf", "scheduler": address}
    return cfg


@pytest.mark.parametrize("processes", [False, True])
def test_distributed_build_identical_to_threads(inputs, tmp_path, processes):
    threads = inputs["root"] / "threads"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=processes,
                                  dashboard_address=None, silence_logs=40) as cluster:
        cfg = _with_scheduler(inputs["cfg"], cluster.scheduler_address)
        for name in ("product.nc", "product.zarr"):
            build_product(inputs["currents"], inputs["bathymetry"], cfg, "tiny",
                          tmp_path / name, tmp_path / f"{name}.json")
        # the client was closed: nothing is left as dask's default scheduler
        with distributed.Client(cluster.scheduler_address) as client:
            assert len(client.scheduler_info()["workers"]) == 2
            # the workers' HDF5 chunk cache was small during the build and is restored after it
            if processes:
                import netCDF4

                caches = client.run(lambda: netCDF4.get_chunk_cache()[0])
                assert set(caches.values()) == {netCDF4.get_chunk_cache()[0]}
    assert sha256_file(tmp_path / "product.nc") == sha256_file(threads / "product.nc")
    assert store_sha256(tmp_path / "product.zarr") == store_sha256(threads / "product.zarr")
    for name in ("product.nc", "product.zarr"):
        got = json.loads((tmp_path / f"{name}.json").read_text())
        want = json.loads((threads / f"{name}.json").read_text())
        assert got["product"]["sha256"] == want["product"]["sha256"]
        assert got["summary"] == want["summary"]
    with open_product(tmp_path / "product.zarr") as a, open_product(threads / "product.nc") as b:
        assert a.equals(b)
    assert distributed.client._get_global_client() is None


def test_missing_distributed_is_a_config_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(ConfigError, match=r"^product\.scheduler: .*distributed"):
        with compute_scheduler("tcp://127.0.0.1:8786"):
            pass


def test_no_scheduler_means_threads():
    import dask

    with compute_scheduler(None) as client:
        assert client is None and dask.config.get("scheduler") == "threads"
