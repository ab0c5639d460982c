"""Behaviour cloning (method ``bc``): an MLP trained by MSE on the heuristic teacher's actions.

Three stages, each a workflow rule and a pure function here:

* :mod:`.dataset` -- roll out the heuristic on *training* seeds (never the evaluation seed)
  and record, from inside the loop with the true pre-step state, every agent's observation
  and the teacher's action (:func:`~.dataset.build_dataset`);
* :mod:`.train` -- fit a relu MLP by MSE (:mod:`.fit`: the package's own fixed-order fit
  with scikit-learn ``MLPRegressor``'s semantics; features: :mod:`oneocean.tasks.learned`)
  with a validation split by episode, deterministically for a seed (:func:`~.train.train`),
  and write the weights as arrays plus a training report;
* the network then acts inside the episode loop through the task layer's learned
  controller (:mod:`oneocean.tasks.learned`: the features and the forward pass the loop runs
  for every agent and step, method kind ``learned``), so a BC episode costs about what a
  heuristic one does; its weights file is read by :func:`oneocean.tasks.learned.load_weights`.

What BC is here: the heuristic's mission layer (its team-level plan and the target point it
steers to: the observation's goal cue) is kept, and the network replaces its velocity law --
the low-level controller the paper clones (eq. 5).
"""
