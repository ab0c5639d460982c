"""Proof of parity: the built-in heuristic (and the oracle), run as an outside policy through
the public step API (``oneocean.evaluate.evaluate`` with
:class:`oneocean.methods.heuristic.FusedPolicy`: ``reset(briefing)``, then ``act(observation)``
every step), gives the same episodes as its fused cell, bit for bit, on every task and tier.

So a user's policy that is given the same briefing and observations can do anything the
built-in methods do: they use nothing else."""

from __future__ import annotations

import numpy as np
import pytest

from oneocean.evaluate import evaluate
from oneocean.methods.heuristic import FusedPolicy
from oneocean.registry import builtin_task_ids
from oneocean.tasks import run_cell

EPISODES = 3


@pytest.mark.parametrize("tier", [1, 2, 3])
@pytest.mark.parametrize("task", builtin_task_ids())
def test_the_heuristic_through_evaluate_is_its_fused_cell(default_grid, task, tier):
    fused = run_cell(default_grid, task, tier, "heuristic", episodes=EPISODES, seed=1000)
    outside = evaluate(FusedPolicy(task), task, tier, default_grid, episodes=EPISODES,
                       seed=1000, name="heuristic")
    cols = [c for c in fused.columns if fused[c].dtype.kind in "fiub"]
    for c in cols:
        np.testing.assert_array_equal(outside[c].to_numpy(), fused[c].to_numpy(), err_msg=c)


@pytest.mark.parametrize("task", builtin_task_ids())
def test_the_oracle_given_the_truth_through_evaluate_is_its_fused_cell(default_grid, task):
    fused = run_cell(default_grid, task, 2, "oracle", episodes=EPISODES, seed=1000)
    outside = evaluate(FusedPolicy(task, "oracle"), task, 2, default_grid, episodes=EPISODES,
                       seed=1000, name="oracle", info="truth")
    for c in ("success", "T_s", "E", "primary"):
        np.testing.assert_array_equal(outside[c].to_numpy(), fused[c].to_numpy(), err_msg=c)


def test_a_policy_that_does_not_reset_is_told_so():
    with pytest.raises(RuntimeError, match="reset"):
        FusedPolicy("G2G").act(None)
