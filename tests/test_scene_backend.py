"""The scene backend end to end: the tasks' own scenario, judge and accounting around MuJoCo
rigid bodies in a scene (Cell(..., backend="mujoco")), compared with the core on the same
scene and episodes, through the step API, the cell files and the scene tables."""

from __future__ import annotations

import numpy as np
import pytest

from oneocean.backends.mujoco.episodes import SceneEpisodes
from oneocean.backends.mujoco.physics import CONTACT
from oneocean.backends.mujoco.scenes import build_scene
from pandas import read_parquet as read_metrics

from oneocean.engine.recording import read_metrics_meta
from oneocean.tasks import Cell, rollout_to_file
from oneocean.testing import uniform_grid, uniform_temporal

CURRENT = (0.25, 0.1)   # east, north, m/s: the temporal export's current (steady)


@pytest.fixture(scope="module")
def scenes():
    g = uniform_grid(*CURRENT, depth_m=40.0, nx=31, ny=31, dx_m=100.0)
    tmp = uniform_temporal(g, *CURRENT)
    return {kind: build_scene({"name": kind, "kind": kind, "size_m": 600.0,
                               "depth_m": 30.0 if kind != "open_water" else None}, g, tmp)
            for kind in ("open_water", "pier_harbor", "simple_underwater")}


def test_rf_succeeds_in_simple_underwater_at_tier_1(scenes):
    cell = Cell(None, "RF", 1, backend="mujoco", scene=scenes["simple_underwater"])
    df = cell.run("heuristic", 4, 0, "6dof")
    assert df["success"].all()
    n_wp = cell.params["n_waypoints"]
    assert (df["waypoints_reached"] == n_wp).all()
    assert (df["cross_track_error_m"] <= cell.params["xte_max_m"]).all()
    assert (df["violations"] == 0).all()
    # the scene's current reached the agents (gain 1 at Tier 1): |(0.25, 0.1)| m/s
    assert df["current_speed_ms"].to_numpy() == pytest.approx(np.hypot(*CURRENT), rel=1e-6)


@pytest.mark.parametrize("task", ["SK", "G2G"])
def test_same_heuristic_same_seed_open_water_matches_the_core(scenes, task):
    """Same scenario, judge, method and seed; only the physics differs. Tolerance: every
    episode's success agrees, the mean time to success within 20 % and the mean energy proxy
    within 25 %: both backends use the vehicle's drag coefficients, velocity loops and thrust
    limits, but MuJoCo's rigid body has isotropic horizontal added mass (REMUS accelerates
    more slowly from rest), no Coriolis, Munk or lift terms, 0.02 s steps instead of the
    core's implicit 0.5 s substeps and a controller re-evaluated every 0.2 s."""
    core = Cell(None, task, 1, backend="core", scene=scenes["open_water"])
    mj = Cell(None, task, 1, backend="mujoco", scene=scenes["open_water"])
    a = core.run("heuristic", 6, 2, "6dof")
    b = mj.run("heuristic", 6, 2, "6dof")
    assert (a["candidate"].to_numpy() == b["candidate"].to_numpy()).all()   # same episodes
    assert (a["success"].to_numpy() == b["success"].to_numpy()).all()
    assert b["T_s"].mean() == pytest.approx(a["T_s"].mean(), rel=0.20)
    assert b["E"].mean() == pytest.approx(a["E"].mean(), rel=0.25)


def test_collision_with_a_pier_is_counted(scenes):
    """An ROV driven at a pier touches it: the step reports CONTACT and the episode counts
    violations (the judge's standard column), and MuJoCo keeps it out of the pier."""
    scene = scenes["pier_harbor"]
    cell = Cell(None, "SK", 1, backend="mujoco", scene=scene)
    init = cell.reset(1, 0)
    pier = next(s for s in scene.structures if s.kind == "pier")
    # released 12 m west of the pier's west face, at 5 m depth, heading east at it
    init["pos0"] = np.array([[[pier.centre[0] - pier.half[0] - 12.0, 5.0, pier.centre[2]]]])
    ep = cell.episodes(init, None, "6dof", 0)
    ep.set_actions(np.array([[[0.8, 0.0, 0.0]]]))
    codes = []
    for k in range(90):
        ep.run(k + 1)
        codes.append(int(ep.LS.code[0, 0]))
    assert codes[:5] == [0] * 5 and CONTACT in codes
    assert int(ep.LS.viol[0]) >= 1
    assert not pier.contains(np.array([ep.state[0, 0, 0]]), np.array([ep.state[0, 0, 2]]))[0]


def test_step_api_and_cell_file_on_the_scene_backend(scenes, tmp_path):
    from oneocean.envs import OceanVectorEnv
    from oneocean.evaluate import evaluate

    scene = scenes["open_water"]
    env = OceanVectorEnv("G2G", 1, None, num_envs=2, backend="mujoco", scene=scene,
                         autoreset_mode="disabled")
    obs, _ = env.reset(seed=3)
    assert isinstance(env.batch, SceneEpisodes) and np.isfinite(obs).all()
    for _ in range(5):
        obs, rew, term, trunc, info = env.step(np.zeros((2, 1, 3)))
    assert np.isfinite(obs).all() and not term.any()
    auto = OceanVectorEnv("G2G", 1, None, num_envs=2, backend="mujoco", scene=scene)
    obs2, _ = auto.reset(seed=3)              # autoreset: the same first episodes
    np.testing.assert_array_equal(obs2, env.reset(seed=3)[0])
    for _ in range(5):
        obs2, *_ = auto.step(np.zeros((2, 1, 3)))
        obs, *_ = env.step(np.zeros((2, 1, 3)))
    np.testing.assert_array_equal(obs2, obs)

    def goal_seeker(o):   # a user's policy: fly at the goal cue at 1.5 m/s
        g = o[..., :3]
        return 1.5 * g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-9)

    df = evaluate(goal_seeker, "G2G", 1, None, episodes=3, seed=3, backend="mujoco",
                  scene=scene, name="goal_seeker")
    assert df["success"].mean() >= 2 / 3 and (df["method"] == "goal_seeker").all()

    out = tmp_path / "rf.parquet"
    rollout_to_file(None, out, "RF", 2, "heuristic", 2, 0, "6dof", backend="mujoco",
                    scene=scene)
    meta = read_metrics_meta(out)
    assert meta["backend"] == "mujoco" and meta["scene"] == "open_water"
    assert meta["scene_meta"]["clock"]["rate"] == 1.0
    assert "MuJoCo: x east, y north, z up" in meta["scene_meta"]["frames"]
    assert meta["tier_params"]["current_gain"] == 1.5 and len(read_metrics(out)) == 2
    na = tmp_path / "dpt.parquet"   # a task without scene tiers: a not-applicable cell
    rollout_to_file(None, na, "DPT", 2, "heuristic", 2, 0, "6dof", backend="mujoco",
                    scene=scene)
    assert read_metrics_meta(na)["applicable"] is False and len(read_metrics(na)) == 0


def test_cli_evaluate_in_a_scene(scenes, tmp_path):
    """`oneocean evaluate --scene .../scene.json --backend mujoco` scores a user's policy in a
    scene written by the workflow's scene_build (scene_files) and records the backend."""
    import os
    import subprocess
    import sys

    from oneocean.backends.mujoco.scenes import scene_files

    paths = scene_files(scenes["open_water"], tmp_path / "open_water")
    (tmp_path / "seek.py").write_text(
        "import numpy as np\n"
        "def act(obs):\n"
        "    g = obs[..., :3]\n"
        "    return 1.5 * g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-9)\n")
    out = tmp_path / "mine.parquet"
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    r = subprocess.run([sys.executable, "-m", "oneocean.cli", "evaluate", "--task", "G2G",
                        "--tier", "1", "--policy", "seek:act", "--scene", str(paths["meta"]),
                        "--backend", "mujoco", "--episodes", "2", "--seed", "3",
                        "--out", str(out)], cwd=tmp_path, capture_output=True, text=True,
                       env=env)
    assert r.returncode == 0, r.stderr
    meta = read_metrics_meta(out)
    assert meta["backend"] == "mujoco" and meta["scene"] == "open_water"
    assert meta["tier_params"]["goal_distance_m"] == 150   # the scene tier, not the core's
    bad = subprocess.run([sys.executable, "-m", "oneocean.cli", "evaluate", "--task", "G2G",
                          "--tier", "1", "--policy", "seek:act", "--scene",
                          str(tmp_path / "nope.json"), "--backend", "mujoco",
                          "--out", str(tmp_path / "x.parquet")], cwd=tmp_path,
                         capture_output=True, text=True, env=env)
    assert bad.returncode == 2 and "scene file not found" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1 and not (tmp_path / "x.parquet").exists()


def test_scene_media_falls_back_to_what_the_scene_hosts(scenes, tmp_path):
    """Fig. 8's media of a scene: route following when the scene hosts it, else the next
    task or tier it hosts, else the scene alone: never a crash."""
    from oneocean.backends.mujoco.store import scene_media
    from oneocean.errors import DataError

    media = {"width": 96, "height": 72, "fps": 5}
    frames = [tmp_path / "a" / f"keyframe_{k}.png" for k in range(2)] + [tmp_path / "a" / "e.gif"]
    frames[0].parent.mkdir()
    g = uniform_grid(*CURRENT, depth_m=40.0, nx=31, ny=31, dx_m=100.0)
    small = build_scene({"name": "small", "kind": "open_water", "size_m": 160.0}, g,
                        uniform_temporal(g, *CURRENT))
    try:
        out = scene_media(small, ["G2G", "RF", "SK"], [2, 3], 0, "6dof", frames, media)
    except DataError as exc:   # no EGL on this machine
        pytest.skip(str(exc))
    # no G2G leg (150 m and up) fits in 160 m, nor RF's five 60 m legs; its four 55 m legs do
    assert (out["task"], out["tier"]) == ("RF", 2)
    assert all(f.stat().st_size > 500 for f in frames)
    frames2 = [tmp_path / "b" / f"keyframe_{k}.png" for k in range(2)] + [tmp_path / "b" / "e.gif"]
    frames2[0].parent.mkdir()
    tiny = build_scene({"name": "tiny", "kind": "open_water", "size_m": 100.0, "margin_m": 45},
                       g, uniform_temporal(g, *CURRENT))
    out = scene_media(tiny, ["RF"], [3], 0, "6dof", frames2, media)
    assert (out["task"], out["tier"]) == (None, None) and frames2[-1].stat().st_size > 500


def test_ladder_cells_on_the_mujoco_backend_through_the_workflow(tmp_path):
    """rollouts.backend: mujoco runs the ladder's cells in the scene rollouts.scene: a task
    with scene tiers gives scene cells (recording backend and scene), one without them a
    not-applicable cell; never a crash."""
    import copy

    from workflow_helpers import SMALL_CONFIG, run_workflow

    cfg = copy.deepcopy(SMALL_CONFIG)
    cfg["rollouts"].update(backend="mujoco", scene="open_water", methods=["heuristic"],
                           tasks=["G2G", "DPT"], tiers=[1], episodes=2)
    region, v = cfg["region"]["name"], cfg["rollouts"]["variant"]
    want = [f"results/rollouts/{region}/{v}/{t}/tier1/heuristic.parquet" for t in ("G2G", "DPT")]
    run_workflow(tmp_path, targets=want, config=cfg)
    g2g, spc = (read_metrics_meta(tmp_path / w) for w in want)   # spc: DPT, no scene tiers
    assert g2g["backend"] == "mujoco" and g2g["scene"] == "open_water" and g2g["applicable"]
    assert len(read_metrics(tmp_path / want[0])) == 2
    assert g2g["tier_params"]["goal_distance_m"] == 150   # the scene tier
    assert spc["applicable"] is False and "scene_tiers" in spc["reason"]


@pytest.mark.parametrize("task", ["RF", "G2G", "SK", "FT", "SPC"])
def test_scene_tiers_are_monotone_and_multiply_the_current(task):
    """The scene tiers (each row over the core tier) are monotone T1 -> T3 in every tier key
    in its declared direction, and the current multiplier grows: 1, 1.5, 2."""
    from task_helpers import assert_tier_table_monotone

    from oneocean.registry import scene_tasks
    from oneocean.tasks.tiers import load_task_table, tier_params

    assert task in scene_tasks()
    table = load_task_table(task)
    rows = {k: tier_params(task, k, scene=True) for k in (1, 2, 3)}
    assert [rows[k].pop("current_gain") for k in (1, 2, 3)] == [1.0, 1.5, 2.0]
    assert_tier_table_monotone({"tiers": rows, "harder": table["harder"]})
    assert any(rows[1][k] != table["tiers"][1][k] for k in table["scene_tiers"][1]
               if k != "current_gain")   # the scene scale differs from the core's
