"""PPO (method ``ppo``): a reinforcement-learning baseline trained through the step API.

Stable-Baselines3's PPO with its default hyperparameters and ``MlpPolicy``, one policy per
single-vehicle task (G2G, SK, RF, DPT by default), trained on the task's vector env
(:class:`oneocean.envs.OceanVectorEnv` through :class:`oneocean.sb3.SB3VecEnv`) in the
normalised observation and action modes with the dense reward, on *training* seeds only:
:data:`.train.TRAINING_SEEDS` (0-999), never the evaluation seed
(:data:`oneocean.vocab.EVALUATION_SEED`) or a replicate seed, checked before training
(:func:`.train.check_training_seeds`).

* :mod:`.train` -- :func:`~.train.train` one task for a fixed budget of environment steps
  (deterministic for a seed: one torch thread, CPU, seeded SB3), and
  :func:`~.train.train_to_files`: the SB3 ``.zip`` (byte-stable) and a JSON training report
  (budget, seeds, wall time, the final success rate on the training episodes, the learning
  curve per rollout);
* :mod:`.policy` -- the trained network as a ``callable`` method (:func:`~.policy.load`):
  raw observations in, mapped through :func:`oneocean.envs.normalize`, deterministic actions
  mapped back to m s-1, scored by :func:`oneocean.evaluate.evaluate` on exactly the cell's
  episodes; :func:`~.policy.evaluate_to_file` writes the cell file the tables read
  (``results/rollouts/<region>/<variant>/<task>/tier<k>/ppo.parquet``).

PPO sees what the heuristic sees (the shared sensor models: the goal cue from its navigation
estimate, its current estimate); it has no plan or controller of its own beyond the network.
Needs the ``rl`` extra (``pip install "oneocean[rl]"``: PyTorch, stable-baselines3,
SuperSuit); importing this package does not import them.
"""

from .policy import METHOD  # noqa: F401  (registers the method ``ppo``
