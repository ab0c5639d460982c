"""Behaviour cloning (method ``bc``): an MLP trained by MSE on the heuristic teacher's actions.

Three stages, each a workflow rule and a pure function here:

* :mod:`.dataset` -- roll out the heuristic on *training* seeds (never the evaluation seed)
  and record, from inside the loop with the true pre-step state, every agent's observation
  and the teacher's action (:func:`~.dataset.build_dataset`);
* :mod:`.train` -- fit scikit-learn's ``MLPRegressor`` (features: :mod:`.kernel`) with a
  validation split by episode, deterministically for a seed (:func:`~.train.train`), and
  write the weights as arrays plus a training report;
* :mod:`.kernel` -- the features and the forward pass the episode loop runs for every agent
  and step (method kind ``learned``), so a BC episode costs about what a heuristic one does.

What BC is here: the heuristic's mission layer (its team-level plan and the target point it
steers to: the observation's goal cue) is kept, and the network replaces its velocity law --
the low-level controller the paper clones (eq. 5).
"""

from __future__ import annotations

import numpy as np

#: Arrays of a weights file (:func:`load_weights`).
WEIGHT_KEYS = ("mu", "sd", "w", "b", "dims", "tasks", "features")


def load_weights(path) -> dict:
    """The arrays of a BC weights file (``.npz`` written by :func:`.train.write_weights`);
    a missing or malformed file is a one-line ``ConfigError`` naming it."""
    from ...errors import ConfigError

    try:
        with np.load(path, allow_pickle=False) as z:
            out = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: not a BC weights file ({exc.__class__.__name__}: "
                          f"{str(exc).splitlines()[0] if str(exc) else ''})") from None
    missing = [k for k in WEIGHT_KEYS if k not in out]
    if missing:
        raise ConfigError(f"{path}: BC weights file lacks {', '.join(missing)}")
    return out
