"""Coastal model output (oneocean.sources.model): the real MOHID (regular) and FVCOM
(unstructured) fixtures, a ROMS (curvilinear) file written here with known currents, and bad
inputs."""

import json

import numpy as np
import pytest
import xarray as xr

from oneocean.config import load_config
from oneocean.errors import DataError
from oneocean.product.build import build_product
from oneocean.sources import fetch_bathymetry, fetch_currents
from oneocean.sources.model import LAND_ELEVATION_M, detect, read_model
from workflow_helpers import REPO

MOHID = "mohid_arousa_2d_hydrodynamic_2024-02-02.nc4"
FVCOM = "fvcom_sfbofs_golden_gate_2024-05-23.nc"


def _cfg(name, shared_data, path):
    return load_config(REPO / "config" / "config.yaml",
                       REPO / "config" / "regions" / f"{name}.yaml",
                       overrides={"files": {"currents": str(shared_data / path),
                                            "bathymetry": str(shared_data / path)}})


def _hourly(times):
    step = np.diff(times.astype("datetime64[s]").astype(np.int64))
    return bool(np.all(step == 3600))


def _reverses(u, v):
    """The domain-mean current along its principal axis takes both signs over the record."""
    mu = np.nanmean(u, axis=tuple(range(1, u.ndim)))
    mv = np.nanmean(v, axis=tuple(range(1, v.ndim)))
    _, _, vt = np.linalg.svd(np.c_[mu, mv] - 0.0, full_matrices=False)
    along = np.c_[mu, mv] @ vt[0]
    return along.min() < 0.0 < along.max()


# --- the real files ---------------------------------------------------------------------------

@pytest.fixture(scope="module")
def arousa(shared_data, tmp_path_factory):
    cfg = _cfg("ria_de_arousa_files", shared_data, MOHID)
    root = tmp_path_factory.mktemp("arousa")
    fetch_currents(cfg, root / "currents.nc", root / "dl")
    fetch_bathymetry(cfg, root / "bathymetry.nc", root / "dl")
    build_product(root / "currents.nc", root / "bathymetry.nc", cfg, "tiny",
                  root / "product.nc", root / "meta.json")
    return cfg, root


def test_mohid_regular_reader_values_mask_and_tide(arousa, shared_data):
    cfg, root = arousa
    assert detect(shared_data / MOHID) == "regular"
    with xr.open_dataset(root / "currents.nc") as cur, \
            xr.open_dataset(root / "bathymetry.nc") as bat, \
            xr.open_dataset(shared_data / MOHID) as src:
        speed = np.hypot(cur["u"], cur["v"]).values
        assert np.nanmax(speed) == pytest.approx(0.88, abs=0.01)       # README: max 0.88
        assert _hourly(cur["time"].values) and cur.sizes["time"] == 24
        # 2-D model: uniform in depth where the water is deep enough
        np.testing.assert_array_equal(cur["u"].isel(depth=0).values,
                                      cur["u"].sel(depth=1.0).values)
        assert _reverses(cur["u"].isel(depth=0).values, cur["v"].isel(depth=0).values)
        # elevation: -bathymetry in the water, +LAND on the file's land (mask == 1, CF)
        s = src.sel(lat=bat["latitude"], lon=bat["longitude"], method="nearest")
        land = s["mask"].values == 1
        np.testing.assert_array_equal(bat["elevation"].values >= 0, land)
        np.testing.assert_allclose(bat["elevation"].values[~land],
                                   -s["bathymetry"].values[~land], rtol=1e-6)
        assert np.all(bat["elevation"].values[land] == LAND_ELEVATION_M)
        assert np.all(np.isnan(cur["u"].isel(time=0, depth=0).values[land]))
        notes = " ".join(json.loads(cur.attrs["model_notes"]))
        assert "no units attribute; taken as m s-1" in notes and "-9999" in notes
        assert "model's own tidal flow" in cur.attrs["tide_in_currents"]


def test_mohid_product_records_its_own_tide(arousa):
    cfg, root = arousa
    with xr.open_dataset(root / "product.nc") as p:
        assert p.attrs["has_tide"] == 0 and "u_tide" not in p
        assert "model's own tidal flow" in p.attrs["tide_in_currents"]
        assert p.attrs["model_layout"] == "regular"
        assert _hourly(p["time"].values) and p.sizes["time"] == 24
        assert np.nanmax(np.hypot(p["u"], p["v"]).values) > 0.6


def test_fvcom_unstructured_reader(shared_data, tmp_path):
    cfg = _cfg("golden_gate_files", shared_data, FVCOM)
    assert detect(shared_data / FVCOM) == "unstructured"
    cur, bat = read_model(shared_data / FVCOM, cfg["region"])
    speed = np.hypot(cur["u"], cur["v"]).values
    assert np.nanmax(speed) == pytest.approx(1.30, abs=0.1)           # README: max 1.30
    assert _hourly(cur["time"].values) and cur.sizes["time"] == 10   # 15 s jitter rounded
    assert _reverses(cur["u"].isel(depth=0).values, cur["v"].isel(depth=0).values)
    elev = bat["elevation"].values
    water = elev < 0
    with xr.open_dataset(shared_data / FVCOM) as src:
        assert -elev[water].min() <= float(src["h"].max()) + 1e-3
        assert -elev[water].max() >= float(src["h"].min()) - 1e-3
    # currents only in the water and never below the sea floor
    u0 = cur["u"].isel(time=0).values
    assert np.all(np.isnan(u0[:, ~water]))
    below = cur["depth"].values[:, None, None] > -elev[None]
    assert np.all(np.isnan(u0[below]))
    assert "sigma layers" in cur.attrs["model_notes"]


# --- ROMS: a curvilinear, rotated, staggered, s-level file with known currents -------------------

def _ue(lon, lat, depth):
    return 0.3 + 2.0 * (lon + 9.0) - 0.004 * depth


def _vn(lon, lat, depth):
    return -0.2 + 3.0 * (lat - 42.5) + 0.002 * depth


def _write_roms(path, drop=(), angle_rad=0.3):
    ny, nx, n = 30, 40, 10
    j, i = np.mgrid[0:ny, 0:nx].astype(float)
    d = 0.002
    ca, sa = np.cos(angle_rad), np.sin(angle_rad)
    def lonlat(jj, ii):
        return -9.0 + d * (ii * ca - jj * sa), 42.5 + d * (ii * sa + jj * ca)
    lon_r, lat_r = lonlat(j, i)
    lon_u, lat_u = lonlat(j[:, :-1], i[:, :-1] + 0.5)
    lon_v, lat_v = lonlat(j[:-1] + 0.5, i[:-1])
    h = np.full((ny, nx), 50.0)
    s = (np.arange(n) - n + 0.5) / n                        # -0.95 .. -0.05
    depth = -s * 50.0                                        # Vtransform 2, Cs_r = s, zeta = 0
    times = np.array(["2024-01-01T00", "2024-01-01T01"], "datetime64[ns]")
    def grid_uv(lon, lat):
        ue = _ue(lon[None, None], lat[None, None], depth[None, :, None, None])
        vn = _vn(lon[None, None], lat[None, None], depth[None, :, None, None])
        ue, vn = np.repeat(ue, 2, 0), np.repeat(vn, 2, 0)
        return ue * ca + vn * sa, -ue * sa + vn * ca        # xi, eta components
    u, _ = grid_uv(lon_u, lat_u)
    _, v = grid_uv(lon_v, lat_v)
    mask = np.ones((ny, nx))
    mask[:, :3] = 0                                         # a strip of land on the west
    ds = xr.Dataset(
        {"u": (("ocean_time", "s_rho", "eta_u", "xi_u"), u, {"units": "meter second-1"}),
         "v": (("ocean_time", "s_rho", "eta_v", "xi_v"), v, {"units": "meter second-1"}),
         "zeta": (("ocean_time", "eta_rho", "xi_rho"), np.zeros((2, ny, nx))),
         "h": (("eta_rho", "xi_rho"), h), "mask_rho": (("eta_rho", "xi_rho"), mask),
         "angle": (("eta_rho", "xi_rho"), np.full((ny, nx), angle_rad)),
         "Cs_r": (("s_rho",), s), "hc": ((), 5.0), "Vtransform": ((), 2)},
        coords={"ocean_time": times, "s_rho": s,
                "lon_rho": (("eta_rho", "xi_rho"), lon_r),
                "lat_rho": (("eta_rho", "xi_rho"), lat_r),
                "lon_u": (("eta_u", "xi_u"), lon_u), "lat_u": (("eta_u", "xi_u"), lat_u),
                "lon_v": (("eta_v", "xi_v"), lon_v), "lat_v": (("eta_v", "xi_v"), lat_v)})
    ds = ds.drop_vars(list(drop))
    ds.to_netcdf(path)
    return ds


def _roms_region(bbox=None):
    # default: inside the rotated grid, away from its edge rows (where rho values are copied
    # from the outermost u/v points rather than averaged)
    return {"bbox": bbox or {"west": -8.982, "east": -8.962, "south": 42.53, "north": 42.55},
            "time": {"start": "2024-01-01T00:00:00", "end": "2024-01-01T01:00:00"},
            "max_depth_m": 40.0}


def test_roms_curvilinear_reader_reproduces_known_currents(tmp_path):
    path = tmp_path / "roms.nc"
    _write_roms(path)
    assert detect(path) == "curvilinear"
    cur, bat = read_model(path, _roms_region())
    lon, lat = np.meshgrid(cur["longitude"].values, cur["latitude"].values)
    for z in (5.0, 10.0, 20.0, 30.0, 40.0):                 # inside the s-levels (2.5..47.5 m)
        u = cur["u"].sel(depth=z).isel(time=1).values
        v = cur["v"].sel(depth=z).isel(time=1).values
        ok = np.isfinite(u)
        assert ok.mean() > 0.8
        np.testing.assert_allclose(u[ok], _ue(lon, lat, z)[ok], atol=1e-4)
        np.testing.assert_allclose(v[ok], _vn(lon, lat, z)[ok], atol=1e-4)
    elev = bat["elevation"].values
    assert np.allclose(elev[elev < 0], -50.0)


def test_roms_land_strip_is_land(tmp_path):
    path = tmp_path / "roms.nc"
    _write_roms(path)
    cur, bat = read_model(path, _roms_region({"west": -9.005, "east": -8.98,
                                              "south": 42.5, "north": 42.54}))
    assert (bat["elevation"].values >= 0).any() and (bat["elevation"].values < 0).any()
    land = bat["elevation"].values >= 0
    assert np.all(np.isnan(cur["u"].isel(time=0, depth=0).values[land]))


# --- bad inputs: one line naming the file and the variable ---------------------------------------

def _one_line(err, *words):
    msg = str(err.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_missing_variable(tmp_path):
    path = tmp_path / "roms_no_v.nc"
    _write_roms(path, drop=("v",))
    with pytest.raises(DataError) as err:
        read_model(path, _roms_region())
    _one_line(err, str(path), "'v'")


def test_no_coordinates(tmp_path, shared_data):
    with xr.open_dataset(shared_data / MOHID) as src:
        ds = src[["u", "v", "bathymetry", "mask"]].load()
    ds = ds.rename({"lon": "i", "lat": "j"}).drop_vars(["i", "j"])
    path = tmp_path / "no_coords.nc"
    ds.to_netcdf(path)
    with pytest.raises(DataError) as err:
        read_model(path, _roms_region())
    _one_line(err, str(path), "u", "coordinates")


def test_bbox_outside_the_model(shared_data):
    region = dict(_roms_region({"west": 2.0, "east": 3.0, "south": 51.0, "north": 52.0}))
    for name in (MOHID, FVCOM):
        with pytest.raises(DataError) as err:
            read_model(shared_data / name, region)
        _one_line(err, name)


def test_implausible_unitless_velocity_and_inverted_mask(tmp_path, shared_data):
    with xr.open_dataset(shared_data / MOHID) as src:
        ds = src[["u", "v", "bathymetry", "mask"]].load()
    region = {"bbox": {"west": -9.1, "east": -8.8, "south": 42.4, "north": 42.6},
              "time": {"start": "2024-02-02T00:00:00", "end": "2024-02-02T23:00:00"},
              "max_depth_m": 8.0}
    fast = ds.copy()
    fast["u"] = fast["u"] * 100.0                           # cm/s written without units
    fast.to_netcdf(tmp_path / "fast.nc")
    with pytest.raises(DataError) as err:
        read_model(tmp_path / "fast.nc", region)
    _one_line(err, "fast.nc", "u", "no units attribute")
    flipped = ds.copy()
    flipped["mask"] = 1.0 - flipped["mask"]
    flipped.to_netcdf(tmp_path / "flipped.nc")
    with pytest.raises(DataError) as err:
        read_model(tmp_path / "flipped.nc", region)
    _one_line(err, "flipped.nc", "mask", "inverted")


def test_tides_true_rejected_for_model_output(shared_data):
    from oneocean.errors import ConfigError
    cfg = _cfg("ria_de_arousa_files", shared_data, MOHID)
    cfg["sources"]["tides"] = True
    with pytest.raises(ConfigError) as err:
        fetch_currents(cfg, "/nonexistent/never.nc", "/tmp")
    _one_line(err, "sources.tides")


def test_ugrid_mesh_node_currents(tmp_path):
    """A UGRID file (SCHISM-like: 2-D, u/v and depth on the nodes) through the mesh path."""
    import xugrid as xu

    from oneocean.sources.model import _quad_mesh

    lon, lat = np.meshgrid(np.linspace(5.0, 5.1, 25), np.linspace(53.0, 53.08, 20))
    g = _quad_mesh(lon, lat)
    times = np.array(["2024-01-01T00", "2024-01-01T01"], "datetime64[ns]")
    uds = xu.UgridDataset(grids=[g])
    for name, val in (("u", 0.1 + 2.0 * (g.node_x - 5.0)), ("v", -0.1 + 3.0 * (g.node_y - 53.0))):
        uds[name] = xr.DataArray(np.repeat(val[None], 2, 0), dims=("time", g.node_dimension),
                                 attrs={"units": "m s-1"})
    uds["depth"] = xr.DataArray(np.full(g.n_node, 12.0), dims=(g.node_dimension,),
                                attrs={"units": "m", "positive": "down"})
    path = tmp_path / "ugrid.nc"
    uds.ugrid.to_dataset().assign_coords(time=times).to_netcdf(path)
    assert detect(path) == "unstructured"
    cur, bat = read_model(path, {"bbox": {"west": 5.02, "east": 5.08, "south": 53.02,
                                          "north": 53.06},
                                 "time": {"start": "2024-01-01T00:00:00",
                                          "end": "2024-01-01T01:00:00"}, "max_depth_m": 5.0})
    lon_t, _ = np.meshgrid(cur["longitude"].values, cur["latitude"].values)
    u = cur["u"].isel(time=0, depth=0).values
    assert np.isfinite(u).all()
    np.testing.assert_allclose(u, 0.1 + 2.0 * (lon_t - 5.0), atol=1e-5)
    assert np.all(bat["elevation"].values == -12.0)
    assert "depth-averaged" in cur.attrs["model_notes"]


def test_default_point_keeps_off_the_edge_of_a_small_domain():
    """The scene anchor on a few-km domain: the deepest water at the edge does not win."""
    from oneocean.product.exports import EDGE_MARGIN_M, default_point

    lat = np.linspace(37.85, 37.90, 51)                   # ~5.5 km
    lon = np.linspace(-122.52, -122.46, 61)               # ~5.3 km
    valid = np.zeros((3, lat.size, lon.size), np.int8)
    valid[:2, 5:45, 5:55] = 1                            # 2 levels over most of the domain
    valid[2, :3, :] = 1                                  # a deeper strip along the south edge
    ds = xr.Dataset({"valid_mask": (("depth", "latitude", "longitude"), valid)},
                    coords={"latitude": lat, "longitude": lon})
    p_lat, p_lon = default_point(ds)
    assert (p_lat - lat[0]) * 111e3 >= EDGE_MARGIN_M
    assert valid[:, lat == p_lat][:, 0, lon == p_lon].sum() == 2
