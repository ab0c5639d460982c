"""The product as a zarr store: same values, attributes and exports as NetCDF; deterministic,
atomic, hashed by the manifest and checked by ``verify``."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from oneocean.config import load_config
from oneocean.errors import ConfigError
from oneocean.product.exports import export_grid, export_temporal
from oneocean.io import sha256_file
from oneocean.product.zarrio import read_npz
from oneocean.pipeline.manifest import collect_manifest, file_record, verify, write_job_provenance
from oneocean.product.build import build_product, summarise_product
from oneocean.sources import fetch_bathymetry, fetch_currents
from oneocean.product.zarrio import (atomic_dir, is_zarr, open_product, product_filename,
                             store_sha256)

CONFIG = Path(__file__).parents[1] / "config" / "config.yaml"


def small_config() -> dict:
    with open(CONFIG) as fh:
        cfg = yaml.safe_load(fh)
    cfg["region"]["time"] = {"start": "2025-01-01T00:00:00", "end": "2025-01-01T06:00:00"}
    cfg["region"]["max_depth_m"] = 40.0
    cfg["synthetic"].update(resolution_deg=0.006, time_step_hours=2.0,
                            depths_m=[0.5, 10.0, 40.0])
    cfg["variants"]["tiny"] = {"extent_fraction": 0.6, "resolution_deg": 0.008, "hours": 6,
                               "max_depth_m": 40.0}
    return cfg


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("zarr_product")
    cfg = small_config()
    cur, bat = root / "currents.nc", root / "bathymetry.nc"
    fetch_currents(cfg, cur, root / "cache")
    fetch_bathymetry(cfg, bat, root / "cache")
    out = {"root": root, "cfg": cfg, "currents": cur, "bathymetry": bat}
    for name in ("product.nc", "product.zarr"):
        d = root / name.split(".")[1]
        build_product(cur, bat, cfg, "tiny", d / name, d / "metadata.json")
        out[name] = d / name
    return out


def _assert_attrs_equal(a: dict, b: dict, what: str):
    assert sorted(a) == sorted(b), what
    for k in a:
        assert np.array_equal(np.asarray(a[k]), np.asarray(b[k])), f"{what}: attr {k}"


def test_zarr_store_layout(built):
    store = built["product.zarr"]
    assert store.is_dir() and (store / ".zmetadata").is_file()
    # nothing temporary left beside it
    assert sorted(p.name for p in store.parent.iterdir()) == ["metadata.json", "product.zarr"]
    meta = json.loads((store.parent / "metadata.json").read_text())
    assert meta["product"]["sha256"] == store_sha256(store)
    with open_product(store) as ds:
        assert ds["u"].encoding["chunks"][0] == 1           # one time step per chunk
        assert "date_created" not in ds.attrs and "history" not in ds.attrs


def test_zarr_equals_netcdf_values_and_attrs(built):
    with open_product(built["product.nc"]) as nc, open_product(built["product.zarr"]) as zr:
        assert sorted(nc.variables) == sorted(zr.variables)
        _assert_attrs_equal(nc.attrs, zr.attrs, "global")
        for name in nc.variables:
            a, b = nc[name], zr[name]
            assert a.dims == b.dims and a.dtype == b.dtype, name
            np.testing.assert_array_equal(a.values, b.values, err_msg=name)
            _assert_attrs_equal(a.attrs, b.attrs, name)
    # the metadata (summary, grid, content hash) agree as well
    m_nc = json.loads((built["product.nc"].parent / "metadata.json").read_text())
    m_zr = json.loads((built["product.zarr"].parent / "metadata.json").read_text())
    for key in ("summary", "grid", "time_coverage", "depth_levels_m", "config_hash"):
        assert m_nc[key] == m_zr[key], key
    assert m_nc["product"]["content_hash"] == m_zr["product"]["content_hash"]
    assert summarise_product(built["product.zarr"]) == summarise_product(built["product.nc"])


def test_exports_from_zarr_equal_netcdf(built, tmp_path):
    grids = {}
    for name in ("product.nc", "product.zarr"):
        export_grid(built[name], tmp_path / f"{name}.grid.npz")
        export_temporal(built[name], tmp_path / f"{name}.temporal.npz", None, None)
        grids[name] = read_npz(tmp_path / f"{name}.grid.npz", "grid")
        grids[name + "t"] = read_npz(tmp_path / f"{name}.temporal.npz", "temporal")
    for a, b in (("product.nc", "product.zarr"), ("product.nct", "product.zarrt")):
        assert sorted(grids[a]) == sorted(grids[b])
        for key in grids[a]:
            if key == "meta_json":
                continue
            np.testing.assert_array_equal(grids[a][key], grids[b][key], err_msg=key)


def test_zarr_bytes_deterministic(built, tmp_path):
    again = tmp_path / "product.zarr"
    build_product(built["currents"], built["bathymetry"], built["cfg"], "tiny", again,
                  tmp_path / "metadata.json")
    assert store_sha256(again) == store_sha256(built["product.zarr"])
    # rebuilding over an existing store replaces it in place
    build_product(built["currents"], built["bathymetry"], built["cfg"], "tiny", again,
                  tmp_path / "metadata.json")
    assert store_sha256(again) == store_sha256(built["product.zarr"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["metadata.json", "product.zarr"]


def test_failed_zarr_write_leaves_nothing(built, tmp_path):
    target = tmp_path / "product.zarr"
    with pytest.raises(RuntimeError):
        with atomic_dir(target, suffix=".zarr") as tmp:
            (tmp / "part").write_bytes(b"x")
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
    cfg = json.loads(json.dumps(built["cfg"]))
    cfg["region"]["time"]["start"] = "2030-01-01T00:00:00"     # no data in the window
    with pytest.raises(Exception):
        build_product(built["currents"], built["bathymetry"], cfg, "tiny", target,
                      tmp_path / "metadata.json")
    assert list(tmp_path.iterdir()) == []


def test_store_hash_ignores_snakemake_timestamp_and_sees_changes(tmp_path, built):
    store = tmp_path / "copy.zarr"
    shutil.copytree(built["product.zarr"], store)
    h = store_sha256(store)
    (store / ".snakemake_timestamp").write_text("")
    assert store_sha256(store) == h
    chunk = next(p for p in sorted((store / "u").iterdir()) if not p.name.startswith("."))
    chunk.write_bytes(chunk.read_bytes() + b"\0")
    assert store_sha256(store) != h


def test_manifest_and_verify_zarr_store(built, tmp_path):
    root = tmp_path / "run"
    store = root / "results" / "product.zarr"
    shutil.copytree(built["product.zarr"], store)
    rec = file_record(store)
    assert rec["sha256"] == store_sha256(store) and rec["content_sha256"]
    assert rec["bytes"] == sum(p.stat().st_size for p in store.rglob("*") if p.is_file())
    cwd = os.getcwd()
    os.chdir(root)
    try:
        write_job_provenance("prov/p.json", "merge_variant", {"variant": "tiny"},
                             ["results/product.zarr"], [], {})
        export_grid("results/product.zarr", "results/grid.npz")
        write_job_provenance("prov/g.json", "export_grid", {"variant": "tiny"},
                             ["results/grid.npz"], ["results/product.zarr"], {})
        collect_manifest(["prov/p.json", "prov/g.json"], "manifest.json")
        m = json.loads(Path("manifest.json").read_text())
        assert m["artifacts"]["results/grid.npz"]["inputs"][0]["path"] == "results/product.zarr"
        assert verify("manifest.json") == []
        # a rewritten store with the same decoded content passes
        (store / ".zattrs").write_text((store / ".zattrs").read_text() + "\n")
        assert verify("manifest.json") == []
        # changed values: the store and what was made from it are reported
        chunk = store / "elevation" / "0.0"
        shutil.copy(chunk, tmp_path / "chunk.bak")
        import numcodecs
        raw = np.frombuffer(numcodecs.Zstd().decode(chunk.read_bytes()), np.float32).copy()
        raw[0] += 1.0
        chunk.write_bytes(numcodecs.Zstd(level=3).encode(raw.tobytes()))
        problems = verify("manifest.json")
        assert any(p.startswith("results/product.zarr: content hash differs") for p in problems)
        assert any(p.startswith("results/grid.npz: input results/product.zarr changed")
                   for p in problems)
        shutil.rmtree(store)
        assert "results/product.zarr: missing" in verify("manifest.json")
    finally:
        os.chdir(cwd)


def test_product_format_config(tmp_path):
    cfg = load_config(CONFIG)
    assert cfg["product"] == {"format": "netcdf", "scheduler": None}
    assert product_filename(cfg["product"]["format"]) == "product.nc"
    assert product_filename("zarr") == "product.zarr" and is_zarr("a/product.zarr/")
    with pytest.raises(ConfigError, match="product.format"):
        load_config(CONFIG, overrides={"product": {"format": "hdf5"}})
    with pytest.raises(ConfigError, match="product.format"):
        product_filename("hdf5")
    # a NetCDF product keeps its plain-file hash
    assert sha256_file(CONFIG) == file_record(CONFIG)["sha256"]


@pytest.mark.parametrize("product", ["product.nc", "product.zarr"])
def test_zarr_exports_equal_npz_and_load_identically(built, tmp_path, product):
    from oneocean.engine import load_grid
    from oneocean.product.zarrio import read_arrays_zarr

    for kind in ("grid", "temporal"):
        paths = {fmt: tmp_path / f"{kind}.{fmt}" for fmt in ("npz", "zarr")}
        for path in paths.values():
            if kind == "grid":
                export_grid(built[product], path, {"variant": "tiny"})
            else:
                export_temporal(built[product], path, None, None, None, {"variant": "tiny"})
        a, b = read_npz(paths["npz"], kind), read_npz(paths["zarr"], kind)
        assert sorted(a) == sorted(b)
        for key in a:                     # every array, meta_json included: same dtype, values
            assert a[key].dtype == b[key].dtype and a[key].shape == b[key].shape, key
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        assert (paths["zarr"] / ".zmetadata").is_file()
        assert read_arrays_zarr(paths["zarr"]).keys() == b.keys()
        # deterministic bytes; rewriting replaces the store and leaves nothing beside it
        h = store_sha256(paths["zarr"])
        if kind == "grid":
            export_grid(built[product], paths["zarr"], {"variant": "tiny"})
        else:
            export_temporal(built[product], paths["zarr"], None, None, None, {"variant": "tiny"})
        assert store_sha256(paths["zarr"]) == h
        rec = file_record(paths["zarr"])      # the manifest hashes the store and its arrays
        assert rec["sha256"] == h and rec["content_sha256"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "grid.npz", "grid.zarr", "temporal.npz", "temporal.zarr"]
    # the engine loads a zarr grid export to an identical Grid
    g_npz, g_zarr = load_grid(tmp_path / "grid.npz"), load_grid(tmp_path / "grid.zarr")
    assert type(g_npz) is type(g_zarr) and g_npz._fields == g_zarr._fields
    for field, x, y in zip(g_npz._fields, g_npz, g_zarr):
        assert type(x) is type(y), field
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype, field
            np.testing.assert_array_equal(x, y, err_msg=field)
        else:
            assert x == y or (x != x and y != y), field


def test_zarr_export_missing_or_bad_is_one_line(tmp_path):
    from oneocean.errors import DataError

    with pytest.raises(DataError, match=r"grid\.zarr: grid export not found"):
        read_npz(tmp_path / "grid.zarr", "grid export")
    (tmp_path / "bad.zarr").mkdir()
    with pytest.raises(DataError, match=r"bad\.zarr: not a readable zarr grid export"):
        read_npz(tmp_path / "bad.zarr", "grid export")


def test_export_format_config():
    from oneocean.product.zarrio import export_filename

    cfg = load_config(CONFIG)
    assert cfg["exports"] == {"format": "npz"}
    assert export_filename("grid") == "grid.npz"
    assert export_filename("temporal", "zarr") == "temporal.zarr"
    with pytest.raises(ConfigError, match="exports.format"):
        load_config(CONFIG, overrides={"exports": {"format": "hdf5"}})
    with pytest.raises(ConfigError, match="exports.format"):
        export_filename("grid", "hdf5")
