"""Formation transit (FT, a team task) as a PettingZoo parallel env, trained with PPO through
SuperSuit.

SuperSuit turns the parallel env into a vector env with one row per vehicle
(``pettingzoo_env_to_vec_env_v1``) and stacks copies of it into a Stable-Baselines3
``VecEnv`` (``concat_vec_envs_v1``); one PPO policy then drives every vehicle (parameter
sharing). Every vehicle receives the team's reward, and an episode ends for all of them at
once, as in :class:`oneocean.sb3.SB3VecEnv` (which does the same without SuperSuit, for any
task, from an ``OceanVectorEnv``).

Run (needs ``pip install "oneocean[rl]"``; the default grid is built on first use)::

    python examples/supersuit_ft.py --steps 4096

then score the policy on the benchmark's evaluation episodes with
:func:`oneocean.evaluate.evaluate` (``--evaluate``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def make_vec_env(tier: int, grid, copies: int):
    """FT at ``tier`` as an SB3 VecEnv: ``copies`` parallel envs x the team's vehicles."""
    import supersuit as ss
    from stable_baselines3.common.vec_env import VecEnvWrapper

    from oneocean.envs import parallel_env

    class SeedNextReset(VecEnvWrapper):
        """SB3's ``seed()`` (seed the next reset), which SuperSuit's SB3 wrapper lacks, so
        ``PPO(..., seed=s)`` trains on the episodes of seed ``s``."""

        def __init__(self, venv):
            super().__init__(venv)
            self._next = None

        def seed(self, seed=None):
            self._next = seed
            return [seed] * self.num_envs

        def reset(self):
            seed, self._next = self._next, None
            if seed is None:
                return self.venv.reset()
            # SuperSuit's SB3 wrapper forwards a seed through its own seed(), which its
            # ConcatVecEnv does not have: seed the ConcatVecEnv's reset directly
            obs, self.venv.reset_infos = self.venv.venv.reset(seed=seed)
            return obs

        def step_wait(self):
            return self.venv.step_wait()

        def get_attr(self, attr_name, indices=None):
            if attr_name == "render_mode":
                return [self.venv.render_mode] * self.num_envs
            return self.venv.get_attr(attr_name, indices)

    par = parallel_env("FT", tier, grid, obs_mode="normalized", action_mode="normalized",
                       reward="dense")
    vec = ss.pettingzoo_env_to_vec_env_v1(par)
    return SeedNextReset(ss.concat_vec_envs_v1(vec, copies, num_cpus=0,
                                               base_class="stable_baselines3"))


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=4096, help="PPO timesteps (vehicle steps)")
    p.add_argument("--tier", type=int, default=1)
    p.add_argument("--copies", type=int, default=2, help="parallel FT episodes")
    p.add_argument("--seed", type=int, default=0, help="training seed (not 1000: evaluation)")
    p.add_argument("--n-steps", type=int, default=256, help="PPO rollout length per row")
    p.add_argument("--grid", default=None, help="grid export (default: the default region)")
    p.add_argument("--evaluate", type=int, default=0, metavar="EPISODES",
                   help="then score the policy on this many evaluation episodes")
    a = p.parse_args(argv)

    import torch
    from stable_baselines3 import PPO

    from oneocean.product.defaults import resolve_grid
    from oneocean.envs import normalize
    from oneocean.methods.ppo.train import quiet_logger
    from oneocean.vocab import EVALUATION_SEED

    assert a.seed != EVALUATION_SEED, "train on other seeds than the evaluation seed"
    grid = resolve_grid(a.grid)
    env = make_vec_env(a.tier, grid, a.copies)
    torch.set_num_threads(1)
    model = PPO("MlpPolicy", env, n_steps=a.n_steps,
                batch_size=min(64, a.n_steps * env.num_envs), seed=a.seed, device="cpu",
                verbose=0)
    quiet_logger(model)            # SB3's logger without its empty <tempdir>/SB3-* folder
    t0 = time.perf_counter()
    model.learn(total_timesteps=a.steps)
    out = {"timesteps": int(model.num_timesteps), "wall_s": time.perf_counter() - t0,
           "rows": env.num_envs}
    print(f"PPO on FT tier {a.tier}: {out['timesteps']} steps over {env.num_envs} vehicle "
          f"rows in {out['wall_s']:.1f} s")
    if a.evaluate:
        from oneocean.envs import OceanVectorEnv
        from oneocean.evaluate import evaluate

        probe = OceanVectorEnv("FT", a.tier, grid, num_envs=1)
        v_max, reach, t_lim = probe.v_max, probe.reach, probe.t_lim

        class Policy:                       # the public observation in, m s-1 out
            def reset(self, briefing):
                pass

            def act(self, observation):
                e, n, _ = observation.agents.shape
                x = normalize(observation.agents, v_max, reach, t_lim)
                act, _ = model.predict(x.reshape(e * n, -1), deterministic=True)
                act = act.reshape(e, n, 3)
                return v_max * act / np.maximum(np.linalg.norm(act, axis=-1,
                                                               keepdims=True), 1.0)

        df = evaluate(Policy(), "FT", a.tier, grid, episodes=a.evaluate, name="ppo_supersuit")
        out["success_rate"] = float(df["success"].mean())
        print(f"evaluation seed {EVALUATION_SEED}: success {out['success_rate']:.0%} over "
              f"{len(df)} episodes")
    env.close()
    return out


if __name__ == "__main__":
    main()
