"""Behaviour cloning: the teacher dataset, deterministic training, in-loop inference."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import oneocean.engine as E
from oneocean.errors import ConfigError
from oneocean.io import sha256_file, write_npz_atomic
from oneocean.tasks.learned import load_weights
from oneocean.methods.bc.dataset import EXTRA_FIELDS, build_dataset, check_seeds, teacher_rows
from oneocean.tasks.learned import learned_act, feature_names, make_net
from oneocean.methods.bc.train import features, train
from oneocean.tasks import Cell, task_module
from oneocean.tasks.common import ACT_FIELDS, OBS_FIELDS
from oneocean.testing import make_test_grid


@pytest.fixture(scope="module")
def grid():
    return E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))


@pytest.fixture(scope="module")
def dataset(grid):
    df, skipped = build_dataset(grid, ["G2G", "SK"], [1], [100], episodes=4,
                                dynamics="6dof", stride=3, max_rows=400,
                                evaluation_seed=1000)
    assert skipped == []
    return df


@pytest.fixture(scope="module")
def trained(dataset):
    return train(dataset, hidden=(16, 16), epochs=4, seed=3)


def test_training_seeds_must_exclude_the_evaluation_seed():
    with pytest.raises(ConfigError, match="evaluation seed 1000"):
        check_seeds([5, 1000], 1000)
    with pytest.raises(ConfigError, match="at least one"):
        check_seeds([], 1000)


def test_config_refuses_the_evaluation_seed_in_bc_train_seeds(base_config):
    from oneocean.config import validate_config

    base_config.setdefault("bc", {})["train_seeds"] = [1000]
    with pytest.raises(ConfigError, match="bc.train_seeds"):
        validate_config(base_config)


def test_dataset_rows_are_the_pre_step_state_and_teacher_action(grid):
    """Kinematic model, stride 1: consecutive rows of an episode satisfy
    p[k+1] - p[k] = (a[k] + c(p[k], t_k)) dt, so the recorded goal offset and action are the
    state *before* each step (the reference rebuilt it from the post-step pose). The goal
    offset is relative to the teacher's navigation estimate: with the true position it is
    the true pre-step state, which the kinematics pin down."""
    cell = Cell(grid, "G2G", 1)
    df = teacher_rows(cell, 100, 2, "kinematic", stride=1, max_rows=10**6,
                      info="true_position")
    init = cell.reset(2, 100)
    dt = cell.params["dt_s"]
    e0 = df[df["episode"] == 0].sort_values("step")
    # step 0: the goal offset is goal - start
    np.testing.assert_allclose(e0[["goal_dx_m", "goal_dy_m", "goal_dz_m"]].iloc[0],
                               init["goal"][0] - init["pos0"][0, 0], atol=1e-12)
    g = e0[["goal_dx_m", "goal_dy_m", "goal_dz_m"]].to_numpy()
    a = e0[list(ACT_FIELDS)].to_numpy()
    pos = init["goal"][0] - g                      # pre-step positions
    t = init["t0"][0] + e0["step"].to_numpy() * dt
    from oneocean.engine.grid import sample_current
    c = np.array([sample_current(cell.grid, p[0], p[1], p[2], tt) for p, tt in
                  zip(pos, t)])
    v = np.stack([a[:, 0] + c[:, 0], a[:, 1], a[:, 2] + c[:, 1]], axis=1)
    speed = np.linalg.norm(a, axis=1)
    ok = speed <= cell.vehicle.v_max + 1e-9          # unclipped requests
    assert ok[:-1].sum() > 10
    np.testing.assert_allclose((pos[1:] - pos[:-1])[ok[:-1]], (v[:-1] * dt)[ok[:-1]],
                               atol=1e-9)
    assert (df["v_max_ms"] == cell.vehicle.v_max).all()


def test_dataset_keeps_every_stride_th_step_and_caps_rows(dataset):
    assert set(dataset["task"]) == {"G2G", "SK"}
    assert (dataset["step"] % 3 == 0).all()
    assert dataset.groupby(["task", "tier", "seed"]).size().max() <= 400
    assert np.isfinite(dataset[list(ACT_FIELDS)].to_numpy()).all()
    assert list(dataset.columns[6:6 + len(OBS_FIELDS)]) == list(OBS_FIELDS)


def test_training_is_deterministic_to_the_byte(dataset, trained, tmp_path):
    _, w1, rep1 = trained
    _, w2, rep2 = train(dataset, hidden=(16, 16), epochs=4, seed=3)
    _, w3, _ = train(dataset, hidden=(16, 16), epochs=4, seed=4)
    paths = [tmp_path / f"w{i}.npz" for i in range(3)]
    for p, w in zip(paths, (w1, w2, w3)):
        write_npz_atomic(p, w)
    assert sha256_file(paths[0]) == sha256_file(paths[1])
    assert sha256_file(paths[0]) != sha256_file(paths[2])
    assert rep1 == rep2
    assert len(rep1["train_mse"]) == 4 and rep1["n_val"] > 0 and rep1["n_train"] > 0
    # the validation split is whole episodes: the last episode of each cell
    assert rep1["best_val_mse"] == min(rep1["val_mse"])
    # training reduced the loss
    assert rep1["train_mse"][-1] < rep1["train_mse"][0]


def test_weights_file_round_trip(trained, tmp_path):
    _, w, _ = trained
    write_npz_atomic(tmp_path / "w.npz", w)
    back = load_weights(tmp_path / "w.npz")
    for k in w:
        np.testing.assert_array_equal(back[k], w[k])
    assert list(back["tasks"]) == ["G2G", "SK"]
    assert list(back["features"]) == list(feature_names(["G2G", "SK"]))
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(ConfigError, match="bad.npz"):
        load_weights(tmp_path / "bad.npz")


def test_kernel_forward_equals_the_training_forward_pass(dataset, trained):
    """The loop's ``learned_act`` on a recorded observation is bit for bit the prediction the
    training measured (same features, standardisation and forward pass), times v_max."""
    model, w, _ = trained
    tasks = ["G2G", "SK"]
    X = features(dataset, tasks)
    pred = model.predict((X - w["mu"]) / w["sd"])
    for r in range(0, len(dataset), 37):
        row = dataset.iloc[r]
        net = make_net(w, row["task"], 1, 1)
        n_x = len(task_module(row["task"]).OBS_EXTRA)     # the row as the loop holds it
        O = row[list(OBS_FIELDS + EXTRA_FIELDS[:n_x])].to_numpy(np.float64)[None, None]
        out = np.array(learned_act(net, float(row["t_lim_s"]), O, 0, 0, 2.0))
        np.testing.assert_array_equal(out, 2.0 * pred[r])


def test_in_loop_learned_actions_equal_the_forward_pass_of_the_saved_weights(grid, trained,
                                                                         tmp_path):
    """Inside the fused loop, every recorded BC action is the Python-side forward pass of the
    weights file (read back) on the recorded observation, times v_max (to 1e-9; in fact
    equal)."""
    from oneocean.methods.bc.fit import MLP

    _, w, _ = trained
    write_npz_atomic(tmp_path / "w.npz", w)
    saved = load_weights(tmp_path / "w.npz")
    cell = Cell(grid, "G2G", 1)
    df, obs, act = cell.run("bc", 3, 1000, "6dof", observations=True, net=saved)
    live = np.isfinite(act).all(axis=-1)
    o = obs[live]
    rows = pd.DataFrame(o, columns=list(OBS_FIELDS + EXTRA_FIELDS[:2])).assign(
        task="G2G", t_lim_s=float(cell.params["time_limit_s"]))
    for c in EXTRA_FIELDS[2:]:
        rows[c] = np.nan
    Z = (features(rows, ["G2G", "SK"]) - saved["mu"]) / saved["sd"]
    pred = MLP(saved["w"], saved["b"], saved["dims"]).predict(Z)
    assert len(rows) > 50
    np.testing.assert_allclose(act[live], pred * cell.vehicle.v_max, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(act[live], pred * cell.vehicle.v_max)
    assert df["method"].iloc[0] == "bc"


def test_the_fit_is_scikit_learns_mlpregressor(dataset):
    """Same initialisation, minibatch order, gradients and Adam steps as scikit-learn's
    ``MLPRegressor`` fitted by ``partial_fit`` once per epoch (the reference): after three
    epochs the kept weights agree to rounding (1e-12), as do the per-epoch losses."""
    sklearn = pytest.importorskip("sklearn.neural_network")
    from oneocean.methods.bc.train import targets, validation_mask

    _, w, rep = train(dataset, hidden=(16, 16), epochs=3, batch_size=64, seed=5)
    df = dataset.reset_index(drop=True)
    val = validation_mask(df, 0.2)
    Z = (features(df, ["G2G", "SK"]) - w["mu"]) / w["sd"]
    Y = targets(df)
    ref = sklearn.MLPRegressor(hidden_layer_sizes=(16, 16), activation="relu", solver="adam",
                               alpha=1e-5, batch_size=64, learning_rate_init=1e-3,
                               shuffle=True, random_state=np.random.RandomState(5))
    layers = []
    for epoch in range(3):
        ref.partial_fit(Z[~val], Y[~val])
        assert rep["val_mse"][epoch] == pytest.approx(
            np.mean((ref.predict(Z[val]) - Y[val]) ** 2), rel=1e-12)
        layers.append([(c.copy(), i.copy()) for c, i in zip(ref.coefs_, ref.intercepts_)])
    for layer, (c, i) in enumerate(layers[rep["best_epoch"] - 1]):     # the kept epoch
        np.testing.assert_allclose(w["w"][layer, :c.shape[0], :c.shape[1]], c, rtol=0,
                                   atol=1e-12)
        np.testing.assert_allclose(w["b"][layer, :i.shape[0]], i, rtol=0, atol=1e-12)
    assert np.abs(w["w"][0]).max() > 0.1          # a trained network, not zeros


def test_bc_differs_from_its_teacher_and_needs_weights(grid, trained):
    _, w, _ = trained
    cell = Cell(grid, "SK", 1)
    h = cell.run("heuristic", 3, 1000, "6dof")
    b = cell.run("bc", 3, 1000, "6dof", net=w)
    assert list(b["candidate"]) == list(h["candidate"])     # the same episodes
    assert not np.allclose(b["E"], h["E"])
    with pytest.raises(ConfigError, match="trained weights"):
        cell.run("bc", 3, 1000, "6dof")
    with pytest.raises(ConfigError, match="not on 'RF'"):
        Cell(grid, "RF", 1).run("bc", 2, 1000, "6dof", net=w)
