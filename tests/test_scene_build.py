"""Scene construction of the MuJoCo backend: stand-in scenes from config, local grid, clock."""

from __future__ import annotations

import numpy as np
import pytest

from oneocean.backends.mujoco.scenes import SCENE_KINDS, build_scene, scene_files
from oneocean.engine.grid import load_grid, sample_currents
from oneocean.errors import ConfigError
from oneocean.testing import make_test_grid, uniform_grid


def _temporal(grid: dict) -> dict:
    """A synthetic temporal export on the grid's time axis at its origin (distinct series)."""
    t = np.asarray(grid["time_s"], dtype=np.float64)
    w = 2 * np.pi / 44712.0
    return {"time_s": t, "u": 0.3 + 0.1 * np.sin(w * t), "v": -0.2 + 0.05 * np.cos(w * t),
            "u_tide": 0.15 * np.cos(w * t), "v_tide": 0.1 * np.sin(w * t),
            "lat": np.array(float(grid["origin_lat"])), "lon": np.array(float(grid["origin_lon"])),
            "depth": np.array(0.5), "meta_json": np.array('{"source": "synthetic"}')}


@pytest.fixture(scope="module")
def coast():
    g = make_test_grid(nt=5, nz=3, ny=30, nx=40)
    return g, _temporal(g)


@pytest.mark.parametrize("kind", SCENE_KINDS)
def test_every_kind_builds_and_rebuilds_byte_identically(kind, coast, tmp_path):
    g, tmp = coast
    spec = {"name": f"s_{kind}", "kind": kind, "size_m": 300, "resolution_m": 6}
    scene = build_scene(spec, g, tmp)
    assert scene.kind == kind and "stand-in for the paper's" in scene.label
    grid = load_grid(scene.grid_data)
    assert grid.nx == grid.ny == 51 and grid.dx == 6.0
    x0, x1, z0, z1 = scene.extent
    assert x1 - x0 == pytest.approx(300.0) and 0.5 * (x0 + x1) == pytest.approx(0.0, abs=1e-6)
    assert len(scene.structures) == {"dam": 3, "open_water": 0, "pier_harbor": 4,
                                     "simple_underwater": 4}[kind]
    a = scene_files(scene, tmp_path / "a")
    b = scene_files(build_scene(spec, g, tmp), tmp_path / "b")
    for key in ("xml", "grid", "meta"):
        assert a[key].read_bytes() == b[key].read_bytes(), key
    load_grid(a["grid"])
    from oneocean.backends.mujoco.mjcf import import_mujoco

    model = import_mujoco().MjModel.from_xml_path(str(a["xml"]))
    assert model.nhfield == 1 and model.ngeom == 2 + len(scene.structures)


def test_spec_typos_are_one_line_errors_naming_the_key(coast):
    g, tmp = coast
    with pytest.raises(ConfigError, match="sizem") as e:
        build_scene({"name": "x", "kind": "dam", "sizem": 300}, g, tmp)
    assert "\n" not in str(e.value)
    with pytest.raises(ConfigError, match="n_pier") as e:
        build_scene({"name": "x", "kind": "pier_harbor", "structures": {"n_pier": 2}}, g, tmp)
    assert "\n" not in str(e.value)
    with pytest.raises(ConfigError, match="scene.kind"):
        build_scene({"name": "x", "kind": "harbour"}, g, tmp)
    with pytest.raises(ConfigError, match="scene.clock.rate"):
        build_scene({"name": "x", "kind": "dam", "clock": {"rate": 0}}, g, tmp)
    with pytest.raises(ConfigError, match="scene.currents"):
        build_scene({"name": "x", "kind": "dam", "currents": "tidal"}, g, tmp)


def test_anchor_outside_the_grid_is_a_one_line_error(coast):
    g, tmp = coast
    with pytest.raises(ConfigError, match="outside the grid") as e:
        build_scene({"name": "x", "kind": "open_water", "anchor": {"lat": 51.5, "lon": -4.4}},
                    g, tmp)
    assert "\n" not in str(e.value)
    lon_edge = float(g["lon"][-1]) - 1e-4  # inside, but the square leaves the grid
    with pytest.raises(ConfigError, match="leaves the grid"):
        build_scene({"name": "x", "kind": "open_water",
                     "anchor": {"lat": float(g["origin_lat"]), "lon": lon_edge}}, g, tmp)


def test_temporal_current_follows_the_dataset_clock(coast):
    g, tmp = coast
    start, rate = 1800.0, 2.0
    scene = build_scene({"name": "c", "kind": "open_water", "clock": {"start": start,
                                                                     "rate": rate}}, g, tmp)
    grid = load_grid(scene.grid_data)
    assert grid.time_s[0] == 0.0
    assert grid.time0_unix_s == float(g["time0_unix_s"]) + start
    ue = tmp["u"] + tmp["u_tide"]
    vn = tmp["v"] + tmp["v_tide"]
    for t in (0.0, 450.0, 900.0, 2345.0, 7000.0):
        want = (np.interp(start + rate * t, tmp["time_s"], ue),
                np.interp(start + rate * t, tmp["time_s"], vn))
        for x, y, z in ((0.0, 2.0, 0.0), (-120.0, 5.0, 90.0), (100.0, 0.5, -140.0)):
            got = sample_currents(grid, [[x, y, z]], [t])[0]
            assert got == pytest.approx(want, abs=2e-6), (t, x, z)  # float32 storage


def test_field_currents_resample_the_product(coast):
    g, tmp = coast
    scene = build_scene({"name": "f", "kind": "open_water", "currents": "field"}, g, tmp)
    local, src = load_grid(scene.grid_data), load_grid(g)
    pts = np.array([[-100.0, 3.0, 50.0], [60.0, 1.0, -80.0]])
    for t in (0.0, 5000.0):
        assert sample_currents(local, pts, t) == pytest.approx(sample_currents(src, pts, t),
                                                               abs=0.02)
    # the field varies between points (not the temporal injection)
    c = sample_currents(local, pts, 0.0)
    assert np.abs(c[0] - c[1]).max() > 1e-3


def test_surfacing_structures_are_land_and_terrain_is_kept(tmp_path):
    g = uniform_grid(0.1, 0.0, depth_m=30.0)
    tmp = _temporal(g)
    ow = build_scene({"name": "o", "kind": "open_water"}, g, tmp)
    for kind in ("pier_harbor", "dam", "simple_underwater"):
        sc = build_scene({"name": kind, "kind": kind}, g, tmp)
        land = sc.grid_data["land_mask"]
        assert np.array_equal(sc.grid_data["elevation"], ow.grid_data["elevation"])
        n = land.shape[0]
        x0, _, z0, _ = sc.extent
        xs = x0 + sc.resolution_m * np.arange(n)
        zs = z0 + sc.resolution_m * np.arange(n)
        X, Z = np.meshgrid(xs, zs)
        inside = np.zeros_like(land, dtype=bool)
        for s in sc.structures:
            if s.kind == "crest":      # the dam's spillway: submerged, water to the scenario
                assert not s.surfacing and s.centre[1] - s.half[1] == pytest.approx(9.0)
                j, i = int(np.argmin(np.abs(zs - s.centre[2]))), int(np.argmin(np.abs(xs - s.centre[0])))
                assert land[j, i] == 0.0
                continue
            assert s.surfacing
            inside |= s.contains(X, Z)
            cx, _, cz = s.centre
            j, i = int(np.argmin(np.abs(zs - cz))), int(np.argmin(np.abs(xs - cx)))
            if s.contains(xs[i], zs[j]):
                assert land[j, i] == 1.0, s.name
        assert inside.any()
        m = 40.0   # the default boundary band (scenes.MARGIN_M) is land too
        x1, z1 = xs[-1], zs[-1]
        band = (X < x0 + m) | (X > x1 - m) | (Z < z0 + m) | (Z > z1 - m)
        assert np.array_equal(land == 1.0, inside | band)  # the grid has no land of its own
        assert (sc.grid_data["valid_mask"][:, inside] == 0).all()
        assert np.array_equal(ow.grid_data["land_mask"] == 1.0, band)
    nb = build_scene({"name": "o", "kind": "open_water", "margin_m": 0}, g, tmp)
    assert nb.grid_data["land_mask"].sum() == 0


def test_heightfield_matches_the_local_grid(coast):
    """The MJCF heightfield reproduces the local grid's elevation (orientation and scale)."""
    from oneocean.backends.mujoco.mjcf import import_mujoco, scene_xml
    from oneocean.engine.grid import sample_elevation_points

    g, tmp = coast
    m_lon = float(g["m_per_deg_lon"])
    lon = float(g["origin_lon"]) - 2250.0 / m_lon  # on the coast: land to the west
    scene = build_scene({"name": "c", "kind": "open_water", "size_m": 400, "resolution_m": 8,
                         "margin_m": 0, "anchor": {"lat": float(g["origin_lat"]), "lon": lon}},
                        g, tmp)
    land = scene.grid_data["land_mask"]
    assert land[:, 0].mean() > 0.5 and land[:, -1].max() == 0.0  # coast inside the square
    mujoco = import_mujoco()
    model = mujoco.MjModel.from_xml_string(scene_xml(scene))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    grid = load_grid(scene.grid_data)
    x0, x1, z0, z1 = scene.extent
    rng = np.random.default_rng(0)
    pts = np.stack([rng.uniform(x0 + 1, x1 - 1, 40), rng.uniform(z0 + 1, z1 - 1, 40)], axis=1)
    want = sample_elevation_points(grid, np.ascontiguousarray(pts), np.empty(40))
    hf = model.geom("seafloor").id
    got = []
    for x, z in pts:
        gid = np.zeros(1, np.int32)
        dist = mujoco.mj_ray(model, data, np.array([x, z, 500.0]), np.array([0.0, 0.0, -1.0]),
                             np.array([1, 0, 0, 0, 0, 0], np.uint8), 1, -1, gid)  # group 0
        assert gid[0] == hf
        got.append(500.0 - dist)
    # MuJoCo triangulates each cell (the grid interpolates bilinearly): compare within the
    # cell's relief
    relief = np.abs(np.diff(scene.grid_data["elevation"], axis=1)).max()
    assert np.abs(np.array(got) - want).max() < relief
    assert np.corrcoef(got, want)[0, 1] > 0.99
