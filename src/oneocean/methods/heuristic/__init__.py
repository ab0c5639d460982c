"""The fused heuristic and oracle policy of every task, one module per task (same name as the
task's module in :mod:`oneocean.tasks`). Each exposes ``plan`` and ``act`` (the policy hooks of
:mod:`oneocean.tasks.loop`), ``SENSING`` (method -> what it knows) and
``params(method, tier, vehicle)`` (the NamedTuple ``M`` its hooks read)."""

#: Fused methods of these modules -> their information level (:data:`oneocean.sensing.
#: INFO_LEVELS`): the heuristic senses through the sensor models every non-oracle method
#: shares (forecast + filtered in-situ current, dead-reckoning navigation); the oracle is
#: given the true current and its true position.
SENSING = {"heuristic": "sensors", "oracle": "truth"}
