"""A real region end to end: the southern North Sea product from the GLO12 daily currents and
the ETOPO 2022 files."""

import json

import numpy as np
import pytest
import xarray as xr

from oneocean.config import load_config
from oneocean.engine import grid as G
from oneocean.product.exports import export_grid, export_temporal
from oneocean.product.build import build_product
from oneocean.sources import fetch_bathymetry, fetch_currents
from test_exports import check_engine_matches_temporal
from workflow_helpers import REPO

CMEMS = "cmems_glo12_currents_P1D_w-1_e10_s50_n55_2025-01-01.nc"
ETOPO = "etopo2022_30s_w2_e3_s51_n53.nc"


def _north_sea(shared_data, root, currents, variant="public"):
    """Fetch (source kind "files") and build a southern North Sea product from ``currents``."""
    cfg = load_config(REPO / "config" / "config.yaml",
                      REPO / "config" / "regions" / "southern_north_sea_files.yaml",
                      overrides={"files": {"currents": str(currents),
                                           "bathymetry": str(shared_data / ETOPO)}})
    cur, bat = root / "currents.nc", root / "bathymetry.nc"
    fetch_currents(cfg, cur, root / "dl")
    fetch_bathymetry(cfg, bat, root / "dl")
    out = root / "product.nc"
    build_product(cur, bat, cfg, variant, out, root / "metadata.json")
    return out


@pytest.fixture(scope="module")
def north_sea(shared_data, tmp_path_factory):
    return _north_sea(shared_data, tmp_path_factory.mktemp("north_sea"), shared_data / CMEMS)


def test_north_sea_product_masks_follow_bathymetry_and_cmems_nan_pattern(north_sea, shared_data,
                                                                         tmp_path):
    with xr.open_dataset(north_sea) as p, xr.open_dataset(shared_data / CMEMS) as src:
        assert p.attrs["source"] == "files"
        land = p["land_mask"].values.astype(bool)
        current = p["current_mask"].values.astype(bool)
        elev = p["elevation"].values
        # land from the bathymetry only: open water without currents is not land
        np.testing.assert_array_equal(land, elev >= 0)
        assert 0.0 < land.mean() < 0.5  # the French and Belgian coasts are in the box
        np.testing.assert_array_equal(current, p["valid_mask"].values.any(axis=0))
        assert not (current & land).any()
        surf = src["uo"].isel(time=0, depth=0)
        # the four GLO12 nodes around every product node
        lat, lon = p["latitude"].values, p["longitude"].values
        j = np.searchsorted(surf["latitude"].values, lat) - 1
        i = np.searchsorted(surf["longitude"].values, lon) - 1
        wet = np.isfinite(surf.values)
        corners = np.stack([wet[j][:, i], wet[j + 1][:, i], wet[j][:, i + 1],
                            wet[j + 1][:, i + 1]])
        all_dry, all_wet = ~corners.any(0), corners.all(0)
        # GLO12 land has no current; coastal water GLO12 does not cover is water without
        # currents (173 nodes, 0.6 % of the grid; it was "land" before issue #9)
        assert all_dry.any() and not current[all_dry].any()
        assert (~current & ~land).sum() > 50
        # water on GLO12 deeper than the first current level in ETOPO has currents
        sea = all_wet & (elev < -float(p["depth"][0]))
        assert sea.sum() > 100
        assert current[sea].all() and not land[sea].any()
        u0 = p["u"].isel(time=0, depth=0).values
        assert np.isfinite(u0[sea]).all() and np.isnan(u0[~current]).all()
        assert p["valid_mask"].isel(depth=0).values[sea].all()

    export_grid(north_sea, tmp_path / "grid.npz", {"region": "southern_north_sea_files",
                                                   "variant": "public"})
    g = np.load(tmp_path / "grid.npz")
    assert np.isfinite(g["u"]).all() and g["land_mask"].shape == land.shape
    np.testing.assert_array_equal(g["current_mask"] == 1, current)
    grid = G.load_grid(tmp_path / "grid.npz")
    # water without currents: current 0 at its nodes, and flagged by current_defined
    jj, ii = np.nonzero(~current & ~land)
    xz = np.column_stack([grid.x0 + ii * grid.dx, grid.z0 + jj * grid.dz])
    assert len(xz) > 50 and np.abs(G.current_coverage(grid, xz)).max() < 1e-12
    xyz = np.column_stack([xz[:, 0], np.full(len(xz), 1.0), xz[:, 1]])
    assert np.abs(G.sample_currents(grid, xyz, 0.0)).max() < 1e-12


def test_north_sea_engine_sampling_equals_the_temporal_export(north_sea, tmp_path):
    kinds = check_engine_matches_temporal(north_sea, tmp_path)
    assert kinds["next_to_no_current"] >= 3 and kinds["above_bed_held"] >= 1


def test_surface_only_product_default_depth(shared_data, tmp_path):
    """A CMEMS file with only its first level (0.494 m): the default depth works."""
    with xr.open_dataset(shared_data / CMEMS) as src:
        src.isel(depth=[0]).load().to_netcdf(tmp_path / "surface_only.nc")
    root = tmp_path / "b"
    root.mkdir()
    product = _north_sea(shared_data, root, tmp_path / "surface_only.nc", "tiny")
    with xr.open_dataset(product) as p:
        assert p["depth"].values.tolist() == [pytest.approx(0.494025, abs=1e-6)]
    out = {}
    for name, depth in (("null", None), ("half", 0.5), ("zero", 0.0)):
        export_temporal(product, tmp_path / f"{name}.npz", None, None, depth)
        with np.load(tmp_path / f"{name}.npz") as z:
            out[name] = {k: z[k] for k in z.files}
    assert float(out["null"]["depth"]) == pytest.approx(0.494025, abs=1e-6)
    assert json.loads(str(out["null"]["meta_json"]))["point"]["depth_m_requested"] is None
    for name in ("half", "zero"):
        np.testing.assert_array_equal(out[name]["u"], out["null"]["u"])
    assert np.isfinite(out["null"]["u"]).all() and np.abs(out["null"]["u"]).max() > 0
    with pytest.raises(Exception, match="below the deepest level"):
        export_temporal(product, tmp_path / "deep.npz", None, None, 1.0)
    check_engine_matches_temporal(product, tmp_path, min_points=5)
