"""A real region end to end: Dover Strait product from the GLO12 currents and ETOPO 2022 files."""

import numpy as np
import xarray as xr

from oneocean.config import load_config
from oneocean.exports import export_grid
from oneocean.product import build_product
from oneocean.sources import fetch_bathymetry, fetch_currents
from workflow_helpers import REPO

CMEMS = "cmems_glo12_currents_P1D_w-1_e10_s50_n55_2025-01-01.nc"
ETOPO = "etopo2022_30s_w2_e3_s51_n53.nc"


def test_dover_product_land_mask_follows_cmems_nan_pattern(shared_data, tmp_path):
    cfg = load_config(REPO / "config" / "config.yaml",
                      REPO / "config" / "regions" / "dover_strait_files.yaml",
                      overrides={"files": {"currents": str(shared_data / CMEMS),
                                           "bathymetry": str(shared_data / ETOPO)}})
    cur, bat = tmp_path / "currents.nc", tmp_path / "bathymetry.nc"
    fetch_currents(cfg, cur, tmp_path / "dl")
    fetch_bathymetry(cfg, bat, tmp_path / "dl")
    out = tmp_path / "product.nc"
    build_product(cur, bat, cfg, "public", out, tmp_path / "metadata.json")

    with xr.open_dataset(out) as p, xr.open_dataset(shared_data / CMEMS) as src:
        assert p.attrs["source"] == "files"
        land = p["land_mask"].values.astype(bool)
        assert 0.0 < land.mean() < 0.5  # the French and Belgian coasts are in the box
        surf = src["uo"].isel(time=0, depth=0)
        # the four GLO12 nodes around every product node
        lat, lon = p["latitude"].values, p["longitude"].values
        j = np.searchsorted(surf["latitude"].values, lat) - 1
        i = np.searchsorted(surf["longitude"].values, lon) - 1
        wet = np.isfinite(surf.values)
        corners = np.stack([wet[j][:, i], wet[j + 1][:, i], wet[j][:, i + 1],
                            wet[j + 1][:, i + 1]])
        all_dry, all_wet = ~corners.any(0), corners.all(0)
        # GLO12 land is product land; water on GLO12 deeper than the first current level in
        # ETOPO is ocean (shallower water has no current level above its seafloor)
        assert all_dry.any() and land[all_dry].all()
        sea = all_wet & (p["elevation"].values < -float(p["depth"][0]))
        assert sea.sum() > 100
        assert not land[sea].any()
        u0 = p["u"].isel(time=0, depth=0).values
        assert np.isfinite(u0[sea]).all() and np.isnan(u0[land]).all()
        assert p["valid_mask"].isel(depth=0).values[sea].all()

    export_grid(out, tmp_path / "grid.npz", {"region": "dover_strait_files", "variant": "public"})
    g = np.load(tmp_path / "grid.npz")
    assert np.isfinite(g["u"]).all() and g["land_mask"].shape == land.shape
