"""The fused heuristic and oracle policy of every task, one module per task (same name as the
task's module in :mod:`oneocean.tasks`).

Each is a policy of the public view only (:class:`oneocean.tasks.loop.Ctx`: the task's
briefing and each step's observation) and exposes ``SENSING`` (method -> what it knows),
``params(method, B)`` (its params ``M`` from the briefing), ``memory(B, M)`` (its own arrays
``H``: plans, estimates), optionally ``prepare(B, M, H)`` (a Python planner run once, before
the first step) and the policy hooks ``plan(C, e, k)`` and ``act(C, e, k, i)`` of
:mod:`oneocean.tasks.loop`. :class:`FusedPolicy` runs one of them as an outside policy
through the step API (``oneocean evaluate``), the way a user's policy runs.
"""

from __future__ import annotations

import numpy as np

#: Fused methods of these modules -> their information level (:data:`oneocean.sensing.
#: INFO_LEVELS`): the heuristic senses through the sensor models every non-oracle method
#: shares (forecast + filtered in-situ current, dead-reckoning navigation); the oracle is
#: given the truth (its briefing's forecast is the true field; its observation the true
#: current and position).
SENSING = {"heuristic": "sensors", "oracle": "truth"}


class FusedPolicy:
    """A task's built-in heuristic (or oracle) as an outside policy: ``reset(briefing)``,
    then ``act(observation)`` every step, with nothing else.

    Its decisions are those of the fused cell, bit for bit, when it is given what the fused
    cell's method is given (the heuristic: the step API's briefing and observations; the
    oracle: the truth, ``oneocean.evaluate.evaluate(..., info="truth")``):
    ``tests/test_parity.py``.

    Parameters
    ----------
    task : str
        Task id.
    method : str
        ``"heuristic"`` or ``"oracle"`` (its params: :data:`SENSING`).
    """

    obs_mode = "raw"
    action_mode = "velocity"

    def __init__(self, task: str, method: str = "heuristic"):
        from ...kernels import kernel_module

        if method not in SENSING:
            from ...errors import ConfigError

            raise ConfigError(f"FusedPolicy: method {method!r} is not one of "
                              f"{', '.join(SENSING)}")
        self.task, self.method = task, method
        self.kern = kernel_module(task)
        self.pol = self.kern.POLICY
        self.C = None

    def reset(self, briefing) -> None:
        """Take the briefing of a batch of episodes (the task's ``<ID>Briefing``): the
        policy's params, a fresh memory, its Python planner if it has one.

        Parameters
        ----------
        briefing : NamedTuple
            The task's briefing (``info["briefing"]`` of the step API's reset).
        """
        from ...tasks.loop import Ctx

        B = briefing
        M = self.pol.params(self.method, B)
        H = self.pol.memory(B, M)
        prepare = getattr(self.pol, "prepare", None)
        if prepare is not None:
            prepare(B, M, H)
        self.C = Ctx(B, np.zeros((0, 0, 0)), (), M, H, np.zeros(0))

    def act(self, observation):
        """The actions of a step.

        Parameters
        ----------
        observation : Observation
            The step's observation (:class:`oneocean.evaluate.Observation`: ``agents`` (E, N,
            D), the task's team observation ``team``, and the ``report`` the method files,
            written in place).

        Returns
        -------
        (E, N, 4) float64
            Velocity requests relative to the water (m s-1) and commanded headings (rad, NaN:
            free).
        """
        from ...tasks.common import O_T

        if self.C is None:
            raise RuntimeError("FusedPolicy: call reset(briefing) before act()")
        O = np.ascontiguousarray(observation.agents, dtype=np.float64)
        C = self.C._replace(O=O, T=observation.team, R=observation.report)
        t = O[:, 0, O_T]
        ks = np.where(np.isfinite(t), np.rint(t / float(C.B.dt)), -1).astype(np.int64)
        out = np.full(O.shape[:2] + (4,), np.nan)
        self.kern._policy(C, ks, out, 0, O.shape[0])
        return out
