"""Stable-Baselines3 adapter: an :class:`~oneocean.envs.OceanVectorEnv` as an SB3 ``VecEnv``.

::

    from stable_baselines3 import PPO
    from oneocean.envs import OceanVectorEnv
    from oneocean.sb3 import SB3VecEnv

    venv = OceanVectorEnv("G2G", 1, None, num_envs=8, autoreset_mode="same_step",
                          obs_mode="normalized", action_mode="normalized", reward="dense")
    model = PPO("MlpPolicy", SB3VecEnv(venv), seed=0, device="cpu").learn(100_000)

Semantics
    * every agent of every sub-env is one SB3 env, row ``j * N + i`` for agent ``i`` of
      sub-env ``j`` (``num_envs x N`` rows; one policy for all agents of a team task:
      parameter sharing); observation space = one agent's ``Box`` (``D``,), action space = one
      agent's ``Box`` (3,);
    * every agent receives its team's reward (the sub-env's), and ``done = terminated |
      truncated`` of its sub-env;
    * the step that ends an episode returns the next episode's first observation (the env
      must run in ``autoreset_mode="same_step"``); that row's info holds
      ``terminal_observation`` (the agent's final observation, from ``info["final_obs"]``),
      ``TimeLimit.truncated`` (the time limit ended it and the task did not: SB3 then
      bootstraps the value of the final observation), ``is_success``, every result column of
      the cell table (``success``, ``T_s``, ``E``, ``coll_ratio``, ``violations``, the task's
      metrics) and ``episode`` (``r``: the team's return, ``l``: its length in steps, ``t``:
      seconds since the adapter was made, as SB3's ``Monitor`` writes it, so SB3 logs
      ``ep_rew_mean`` and ``success_rate`` without another wrapper);
    * :meth:`seed` seeds the next :meth:`reset` (the episodes of ``OceanVectorEnv.reset(seed=
      s)``); unseeded, a reset draws its seed from the env's own generator;
    * ``get_attr``/``set_attr``/``env_method`` reach the underlying ``OceanVectorEnv``: every
      row of one vector env is the same object, so ``env_method`` calls a method once per
      vector env and returns its result for each requested row; ``env_is_wrapped`` is False
      (no Gymnasium wrappers); :meth:`render` is the ``rgb_array`` view of sub-env 0;
    * torch's thread count is kept across a reset and the step after it (the env's first
      numba parallel launch resets the process's OpenMP thread count, which torch shares):
      ``torch.set_num_threads(1)`` before training stays in force.

Several vector envs of one task with equal per-agent spaces (e.g. one per tier) can be given
as a list: their rows follow one another, and a seed ``s`` seeds the first with ``s`` and the
``b``-th with :func:`block_seed` ``(s, b)``.

SB3 is imported when :data:`SB3VecEnv` is first used, so the package does not need it
(``pip install "oneocean[rl]"`` installs it).
"""

from __future__ import annotations

import sys
import time

import numpy as np

__all__ = ["SB3VecEnv", "block_seed", "agent_space"]

#: Entropy word of :func:`block_seed` (keeps block seeds apart from the env's pool seeds).
_BLOCK_WORD = 0x5B3


def block_seed(seed: int, block: int) -> int:
    """The seed of the ``block``-th vector env when an adapter over several is seeded.

    Parameters
    ----------
    seed : int
        The adapter's seed.
    block : int
        The vector env's index in the adapter's list, from 0.

    Returns
    -------
    int
        ``seed`` itself for block 0, else a non-negative 31-bit seed drawn from
        ``numpy.random.SeedSequence([seed, 0x5B3, block])``.
    """
    if block == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), _BLOCK_WORD, int(block)])
               .generate_state(1)[0] >> 1)


def agent_space(space):
    """One agent's ``Box`` (the last axis) of a per-sub-env ``Box`` (N, D).

    Parameters
    ----------
    space : gymnasium.spaces.Box
        A sub-env's observation or action space, shape (N, D): one row per agent.

    Returns
    -------
    gymnasium.spaces.Box
        Shape (D,), the first row's bounds, the same dtype.

    Raises
    ------
    ValueError
        The agents' rows have different bounds.
    """
    from gymnasium import spaces

    lo, hi = np.asarray(space.low), np.asarray(space.high)
    if not (np.all(lo == lo[:1]) and np.all(hi == hi[:1])):
        raise ValueError("SB3VecEnv: agents of one sub-env have different space bounds")
    return spaces.Box(lo[0].copy(), hi[0].copy(), dtype=space.dtype)


def _torch_threads() -> int | None:
    """torch's intra-op thread count, if torch is imported (else None)."""
    torch = sys.modules.get("torch")
    return None if torch is None else torch.get_num_threads()


def _restore_torch_threads(n: int | None) -> None:
    """Set torch's thread count back to ``n``: the env's first numba parallel launch resets
    the process's OpenMP thread count (shared with torch) to the number of cores, and more
    torch threads than free cores makes every small torch operation wait (measured: 100 x
    slower per op on a loaded 2-core machine)."""
    if n is not None and sys.modules["torch"].get_num_threads() != n:
        sys.modules["torch"].set_num_threads(n)


def _build():
    from stable_baselines3.common.vec_env import VecEnv

    class SB3VecEnv(VecEnv):
        """Stable-Baselines3 ``VecEnv`` over one :class:`~oneocean.envs.OceanVectorEnv` (or a
        list of them) in ``autoreset_mode="same_step"``: one SB3 env per agent per sub-env
        (see :mod:`oneocean.sb3`).

        Parameters
        ----------
        venv : OceanVectorEnv or list of OceanVectorEnv
            Vector envs made with ``autoreset_mode="same_step"``, with equal per-agent
            spaces; their rows follow one another.

        Raises
        ------
        ValueError
            No vector env, one in another autoreset mode, or per-agent spaces that differ.
        """

        def __init__(self, venv):
            venvs = list(venv) if isinstance(venv, (list, tuple)) else [venv]
            if not venvs:
                raise ValueError("SB3VecEnv: no vector env given")
            for v in venvs:
                if getattr(v, "autoreset", None) != "same_step":
                    raise ValueError("SB3VecEnv: the OceanVectorEnv must be made with "
                                     "autoreset_mode='same_step' (SB3 resets in the step that "
                                     f"ends an episode), got {getattr(v, 'autoreset', None)!r}")
            obs_space = agent_space(venvs[0].single_observation_space)
            act_space = agent_space(venvs[0].single_action_space)
            for v in venvs[1:]:
                if (agent_space(v.single_observation_space) != obs_space
                        or agent_space(v.single_action_space) != act_space):
                    raise ValueError("SB3VecEnv: the vector envs' per-agent spaces differ")
            self.venvs = venvs
            self._rows = []                 # (first row, sub-envs, agents) per vector env
            start = 0
            for v in venvs:
                self._rows.append((start, v.num_envs, v.n_agents))
                start += v.num_envs * v.n_agents
            self._owner = np.concatenate([np.full(v.num_envs * v.n_agents, b)
                                          for b, v in enumerate(venvs)])
            self._next_seed = None
            self._actions = None
            self._ret = [np.zeros(v.num_envs) for v in venvs]
            self._len = [np.zeros(v.num_envs, dtype=np.int64) for v in venvs]
            self._t0 = time.perf_counter()
            self._threads = None            # torch's thread count to keep (set by reset)
            super().__init__(start, obs_space, act_space)

        @property
        def venv(self):
            """The (first) underlying :class:`~oneocean.envs.OceanVectorEnv`."""
            return self.venvs[0]

        # ---------------------------------------------------------------- stepping
        def reset(self):
            """Reset every vector env (seeded by the last :meth:`seed`, then unseeded).

            Returns
            -------
            (rows, D) ndarray
                The first observation of every row.
            """
            out = []
            seed, self._next_seed = self._next_seed, None
            self._threads = _torch_threads()
            for b, v in enumerate(self.venvs):
                obs, _ = v.reset(seed=None if seed is None else block_seed(seed, b))
                out.append(obs.reshape(-1, obs.shape[-1]))
                self._ret[b][:] = 0.0
                self._len[b][:] = 0
            _restore_torch_threads(self._threads)
            self.reset_infos = [{} for _ in range(self.num_envs)]
            self._reset_seeds()
            self._reset_options()
            return np.concatenate(out)

        def step_async(self, actions):
            """Store the actions for :meth:`step_wait`.

            Parameters
            ----------
            actions : (rows, 3) array_like
                One agent's action per row.
            """
            self._actions = np.asarray(actions)

        def step_wait(self):
            """Step every vector env with the stored actions.

            Returns
            -------
            obs : (rows, D) ndarray
                The next observations (a new episode's first where one ended).
            rewards : (rows,) float32
                The team's (sub-env's) reward.
            dones : (rows,) bool
                ``terminated | truncated`` of the sub-env.
            infos : list of dict
                Per row; see the module docstring for the keys of a row whose episode ended.

            Raises
            ------
            RuntimeError
                No :meth:`step_async` before.
            """
            if self._actions is None:
                raise RuntimeError("SB3VecEnv: step_wait() without step_async()")
            acts, self._actions = self._actions, None
            obs_out, rew_out, done_out, infos = [], [], [], []
            for b, (v, (start, e, n)) in enumerate(zip(self.venvs, self._rows)):
                a = acts[start:start + e * n].reshape(e, n, -1)
                obs, r, term, trunc, info = v.step(a)
                done = np.asarray(term) | np.asarray(trunc)
                self._ret[b] += r
                self._len[b] += 1
                rows = [{} for _ in range(e * n)]
                if done.any():
                    final = info.get("final_info", info)
                    cols = [k for k in final if not k.startswith("_")
                            and k not in ("is_success", "final_obs", "final_info")]
                    t = round(time.perf_counter() - self._t0, 6)
                    for j in np.flatnonzero(done):
                        metrics = {k: float(final[k][j]) for k in cols}
                        ep = {"r": float(self._ret[b][j]), "l": int(self._len[b][j]), "t": t}
                        for i in range(n):
                            rows[j * n + i] = {
                                "terminal_observation": np.array(info["final_obs"][j, i]),
                                "TimeLimit.truncated": bool(trunc[j] and not term[j]),
                                "is_success": bool(final["is_success"][j]),
                                **metrics, "episode": dict(ep)}
                    self._ret[b][done] = 0.0
                    self._len[b][done] = 0
                obs_out.append(obs.reshape(e * n, -1))
                rew_out.append(np.repeat(np.asarray(r, dtype=np.float32), n))
                done_out.append(np.repeat(done, n))
                infos += rows
            if self._threads is not None:           # the first step after a reset
                _restore_torch_threads(self._threads)
                self._threads = None
            return (np.concatenate(obs_out), np.concatenate(rew_out),
                    np.concatenate(done_out), infos)

        # ---------------------------------------------------------------- seeding, render
        def seed(self, seed=None):
            """Seed the next :meth:`reset`.

            Parameters
            ----------
            seed : int, optional
                The seed (the ``b``-th vector env gets :func:`block_seed` ``(seed, b)``);
                None: the envs draw their own seeds.

            Returns
            -------
            list
                The seed (int or None) for every row.
            """
            self._next_seed = None if seed is None else int(seed)
            return [self._next_seed] * self.num_envs

        def render(self, mode=None):
            """The ``rgb_array`` view of sub-env 0.

            Parameters
            ----------
            mode : str, optional
                Ignored: the vector env's ``render_mode`` decides.

            Returns
            -------
            (H, W, 3) uint8 ndarray or None
                The frame; None without ``render_mode="rgb_array"``.
            """
            return self.venvs[0].render()

        def get_images(self):
            """The ``rgb_array`` view of sub-env 0, in a list.

            Returns
            -------
            list
                One frame (or None, see :meth:`render`).
            """
            return [self.venvs[0].render()]

        def close(self):
            """Close every vector env."""
            for v in self.venvs:
                v.close()

        # ---------------------------------------------------------------- attributes
        def _targets(self, indices):
            """(vector env, its requested rows) per vector env, in row order."""
            idx = list(self._get_indices(indices))
            by = {}
            for k in idx:
                by.setdefault(int(self._owner[k]), []).append(k)
            return idx, by

        def get_attr(self, attr_name, indices=None):
            """An attribute of the vector env behind each requested row.

            Parameters
            ----------
            attr_name : str
                The attribute.
            indices : None, int or iterable of int, optional
                The rows; None: all.

            Returns
            -------
            list
                The value per requested row.
            """
            idx, _ = self._targets(indices)
            return [getattr(self.venvs[int(self._owner[k])], attr_name) for k in idx]

        def set_attr(self, attr_name, value, indices=None):
            """Set an attribute on the vector envs behind the requested rows (once each).

            Parameters
            ----------
            attr_name : str
                The attribute.
            value : object
                Its new value.
            indices : None, int or iterable of int, optional
                The rows; None: all.
            """
            _, by = self._targets(indices)
            for b in by:
                setattr(self.venvs[b], attr_name, value)

        def env_method(self, method_name, *method_args, indices=None, **method_kwargs):
            """Call a method of the vector envs behind the requested rows (once per vector env).

            Parameters
            ----------
            method_name : str
                The method.
            *method_args
                Its positional arguments.
            indices : None, int or iterable of int, optional
                The rows; None: all.
            **method_kwargs
                Its keyword arguments.

            Returns
            -------
            list
                Each requested row's vector env's result.
            """
            idx, by = self._targets(indices)
            res = {b: getattr(self.venvs[b], method_name)(*method_args, **method_kwargs)
                   for b in by}
            return [res[int(self._owner[k])] for k in idx]

        def env_is_wrapped(self, wrapper_class, indices=None):
            """Whether the rows' envs are wrapped in ``wrapper_class``: never (no Gymnasium
            wrappers).

            Parameters
            ----------
            wrapper_class : type
                A Gymnasium wrapper class.
            indices : None, int or iterable of int, optional
                The rows; None: all.

            Returns
            -------
            list of bool
                False per requested row.
            """
            idx, _ = self._targets(indices)
            return [False] * len(idx)

    return SB3VecEnv


def __getattr__(name):
    if name == "SB3VecEnv":
        cls = _build()
        globals()["SB3VecEnv"] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
