"""Scene routes: every structured scene draws its tasks' routes on its structures (the scene's
part of the scenario, :class:`oneocean.backends.mujoco.scenes.SceneRoutes`), deterministically
from the seed; the judge and the accounting stay the tasks' own."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from oneocean.backends.mujoco.scenes import (LANE_OFFSET_M, ROUTE_CLEAR_M, Structure,
                                             build_scene, route_guide)
from oneocean.tasks import Cell
from oneocean.testing import uniform_grid, uniform_temporal

CURRENT = (0.25, 0.1)


@pytest.fixture(scope="module")
def scenes():
    g = uniform_grid(*CURRENT, depth_m=40.0, nx=31, ny=31, dx_m=100.0)
    tmp = uniform_temporal(g, *CURRENT)
    return {kind: build_scene({"name": kind, "kind": kind, "size_m": 600.0,
                               "depth_m": 30.0 if kind != "open_water" else None}, g, tmp)
            for kind in ("open_water", "dam", "pier_harbor", "simple_underwater")}


def _dense(route, step=0.5):
    t = np.linspace(0.0, 1.0, int(100 / step))
    a, b = route[:-1], route[1:]
    return (a[:, None] + t[None, :, None] * (b - a)[:, None]).reshape(-1, 3)


def _near(s: Structure, pts, d):
    big = Structure(s.name, s.centre, (s.half[0] + d, s.half[1], s.half[2] + d), s.yaw_rad,
                    s.kind)
    return big.contains(pts[:, 0], pts[:, 2])


def test_open_water_has_no_guide_and_structured_scenes_have_one(scenes):
    assert route_guide(scenes["open_water"]) is None
    for kind in ("dam", "pier_harbor", "simple_underwater"):
        assert route_guide(scenes[kind]) is not None


def test_dam_routes_cross_the_spillway_crest_above_it(scenes):
    """Every RF route crosses the dam's footprint, over its submerged spillway crest, at a
    depth at least ROUTE_CLEAR_M above the crest, and never over the surfacing wall."""
    sc = scenes["dam"]
    crest = next(s for s in sc.structures if s.kind == "crest")
    walls = [s for s in sc.structures if s.kind == "wall"]
    init = Cell(None, "RF", 2, backend="mujoco", scene=sc).reset(12, 3)
    for r in init["route"]:
        pts = _dense(r)
        assert crest.contains(pts[:, 0], pts[:, 2]).any()        # over the crest
        assert not any(w.contains(pts[:, 0], pts[:, 2]).any() for w in walls)
        assert r[0, 1] <= crest.centre[1] - crest.half[1] - ROUTE_CLEAR_M + 1e-9
        assert np.ptp(r[:, 1]) == 0.0                            # RF: one depth


def test_pier_and_basin_routes_run_beside_their_structures(scenes):
    """Every route passes within LANE_OFFSET_M (+ margin) of a pier or a basin wall, and
    keeps ROUTE_CLEAR_M off every surfacing structure."""
    for kind, k in (("pier_harbor", "pier"), ("simple_underwater", "basin")):
        sc = scenes[kind]
        for task in ("RF", "G2G"):
            init = Cell(None, task, 2, backend="mujoco", scene=sc).reset(10, 5)
            routes = init["route"] if "route" in init else np.stack(
                [init["pos0"][:, 0], init["goal"][:, 0] if init["goal"].ndim == 3
                 else init["goal"]], axis=1)
            for r in routes:
                pts = _dense(r)
                near = [_near(s, pts, LANE_OFFSET_M[1] + 1.0).any()
                        for s in sc.structures if s.kind == k]
                assert any(near), (kind, task)
                for s in sc.structures:
                    assert not _near(s, pts, ROUTE_CLEAR_M - 0.05).any(), (kind, s.name)


def test_scene_routes_are_deterministic_and_differ_from_obstacle_free_ones(scenes):
    sc = scenes["pier_harbor"]
    a = Cell(None, "RF", 2, backend="mujoco", scene=sc).reset(8, 11)
    b = Cell(None, "RF", 2, backend="mujoco", scene=sc).reset(8, 11)
    for k in a:
        assert np.array_equal(a[k], b[k]), k
    free = Cell(None, "RF", 2, backend="mujoco",
                scene=dataclasses.replace(sc, kind="open_water")).reset(8, 11)
    assert not np.array_equal(a["route"], free["route"])


def test_success_differs_between_scene_routes_and_obstacle_free_routes():
    """RF tier 2, heuristic, one seed, a 0.5 m/s current: the dam scene's routes (over the
    spillway crest, between the wall pieces) and the obstacle-free routes the task draws
    itself in the same scene give different per-episode success (the judge is the task's)."""
    cur = (0.5, 0.2)
    g = uniform_grid(*cur, depth_m=40.0, nx=31, ny=31, dx_m=100.0)
    sc = build_scene({"name": "dam", "kind": "dam", "size_m": 600.0, "depth_m": 30.0}, g,
                     uniform_temporal(g, *cur))
    out = {}
    for label, s in (("scene", sc), ("free", dataclasses.replace(sc, kind="open_water"))):
        out[label] = Cell(None, "RF", 2, backend="mujoco", scene=s).run(
            "heuristic", 8, 7, "6dof")
    a = out["scene"]["success"].to_numpy()
    b = out["free"]["success"].to_numpy()
    assert a.sum() == 8 and b.sum() == 6      # measured: the same on every run (seeded)
    assert not np.array_equal(a, b)


def test_scene_mjcf_has_water_fog_and_a_textured_seafloor(scenes):
    from oneocean.backends.mujoco.mjcf import FOG_END_M, FOG_START_M, import_mujoco, scene_xml

    xml = scene_xml(scenes["pier_harbor"])
    assert "checker" not in xml and 'mark="random"' in xml and 'material="sand"' in xml
    assert "fogstart=" in xml and "<rgba fog=" in xml
    model = import_mujoco().MjModel.from_xml_string(xml)
    assert model.vis.map.fogstart == pytest.approx(FOG_START_M)
    assert model.vis.map.fogend == pytest.approx(FOG_END_M)
    fog = np.asarray(model.vis.rgba.fog)
    assert fog[2] > fog[0] and fog[1] > fog[0]           # blue-green
    assert model.nhfield == 1 and model.ntex >= 2


def test_table7_spread_row_names_the_highest_and_lowest_scene():
    import pandas as pd

    from oneocean.reporting.scene_tables import table7_frame, table7_latex

    rows = []
    for scene, label, succ, viol in (("a", "Dam*", [1, 1, 0, 0], [0, 3, 0, 0]),
                                     ("b", "OpenWater*", [1, 1, 1, 1], [0, 0, 0, 0]),
                                     ("c", "PierHarbor*", [1, 0, 0, 0], [5, 5, 0, 1])):
        ep = pd.DataFrame({"success": np.array(succ, bool), "violations": np.array(viol),
                           "waypoints_reached": np.array([4, 4, 3, 2]),
                           "primary": np.array([1.0, 2.0, 3.0, 4.0])})
        rows.append({"scene": scene, "label": label, "backend": "mujoco", "task": "RF",
                     "tier": 2, "method": "heuristic", "applicable": True, "reason": "",
                     "n": 4, "success": ep["success"].to_numpy(), "episodes": ep,
                     "n_waypoints": 4, "file": ""})
    t7 = table7_frame(pd.DataFrame(rows))
    spread = t7[t7["scene"] == "spread"].iloc[0]
    assert spread["sr"] == pytest.approx(75.0)
    assert spread["reason"] == "OpenWater* - PierHarbor*"
    assert t7.loc[t7["scene"] == "c", "contact_pct"].iloc[0] == pytest.approx(75.0)
    tex = table7_latex(t7, "r", "heuristic", "4 episodes per cell")
    assert "Spread" in tex and "OpenWater* - PierHarbor*" in tex


def test_panel_render_draws_the_slick_and_the_current(scenes, tmp_path):
    """render_media without a GIF (Fig. 8's panels): the slick cells and the current's arrow
    change the picture; the same call gives the same bytes."""
    from oneocean.backends.mujoco.media import render_media
    from oneocean.engine.dynamics import STATE_DIM

    sc = scenes["pier_harbor"]
    traj = np.zeros((3, 2, STATE_DIM))
    traj[:, 0, :3] = [[0.0, 3.0, -100.0 + 5 * k] for k in range(3)]
    traj[:, 1, :3] = [[10.0, 3.0, -100.0 + 5 * k] for k in range(3)]
    C = np.zeros((8, 8))
    C[2:6, 2:6] = 1.0
    field = {"C": C, "origin": (-20.0, -80.0), "h": 10.0}
    size = (96, 72)

    def png(name, **kw):
        out = render_media(sc, "bluerov2_heavy", traj, tmp_path / name, None, keyframes=1,
                           size=size, **kw)
        assert out["gif"] is None and out["frames"] == 0
        return out["png"][0].read_bytes()

    plain = png("a")
    both = png("b", current=(0.4, 0.1), field=field)
    again = png("c", current=(0.4, 0.1), field=field)
    assert both != plain and both == again
