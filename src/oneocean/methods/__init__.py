"""Methods: what the agents do. A method is a policy; a task (``oneocean.tasks``) is the world.

Four kinds (``oneocean.registry.MethodSpec.kind``):

* ``fused``: jitted per-agent policies run inside the episode loop at full speed. The
  built-in ``heuristic`` and ``oracle`` of every task live in :mod:`oneocean.methods.heuristic`
  (one module per task, ``plan``/``act`` hooks of :mod:`oneocean.tasks.loop` plus
  ``params(method, tier, vehicle)``); they differ in the information they use (the heuristic
  senses through the sensor models every non-oracle method shares, :mod:`oneocean.sensing`;
  the oracle knows the true current and its true position) and, where a task has it, in
  planning.
* ``learned``: a trained network evaluated inside the loop with its weights as arrays:
  ``bc`` (:mod:`oneocean.methods.bc`), behaviour cloning of the heuristic's velocity law.
* ``planner``: Python called between K-step segments of the loop, writing plan tokens a
  low-level fused policy follows: the LLM planners ``llm_<name>``
  (:mod:`oneocean.methods.llm`, one per configured model).
* ``callable``: any Python function ``obs -> action`` (:mod:`oneocean.evaluate`),
  stepped through the loop's external-action path; this is how a user scores their own policy
  (:func:`oneocean.evaluate.evaluate`, ``oneocean evaluate``), and how ``ppo``
  (:mod:`oneocean.methods.ppo`, a PPO network trained through the step API) is scored.
"""
