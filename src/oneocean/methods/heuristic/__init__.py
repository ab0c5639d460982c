"""The fused heuristic and oracle policy of every task, one module per task (same name as the
task's module in :mod:`oneocean.tasks`). Each exposes ``plan`` and ``act`` (the policy hooks of
:mod:`oneocean.tasks.loop`), ``SENSING`` (method -> 1 if it senses the current through the
noisy probe) and ``params(method, tier, vehicle)`` (the NamedTuple ``M`` its hooks read)."""

#: Fused methods of these modules -> 1 if the method senses the current through the noisy
#: local probe (the heuristic), 0 if it knows the true current (the oracle).
SENSING = {"heuristic": 1, "oracle": 0}
