"""Per-agent status codes of the core engine: plain ints so kernels can set them.

``OK`` means the last move was accepted. Codes ``>= 10`` are constraint violations: the move
was rejected (position kept, velocity zeroed) and the agent's violation counter incremented.
``TIMEOUT`` is reserved for the task layer (episode ended without success).
"""

from __future__ import annotations

OK = 0
#: The proposed position is on land (sampled land mask >= threshold).
LAND = 10
#: The proposed position is closer to the seafloor than the clearance.
SEAFLOOR = 11
#: The proposed position is outside the horizontal extent of the grid.
OUTSIDE = 12
#: The scene backend: the vehicle touched the seafloor or a structure during the step (a
#: physical contact: MuJoCo resolved it; counted as a violation, the move is not undone).
CONTACT = 13
#: The dynamics produced a non-finite state (a bug or absurd parameters); move rejected.
NONFINITE = 20
#: Episode reached its time limit without success (set by tasks, never by the engine).
TIMEOUT = 30

NAMES = {OK: "ok", LAND: "land", SEAFLOOR: "seafloor", OUTSIDE: "outside",
         CONTACT: "contact", NONFINITE: "nonfinite", TIMEOUT: "timeout"}


def is_violation(code: int) -> bool:
    """Whether a status code counts as a violation.

    Violations are a rejected move (``LAND``, ``SEAFLOOR``, ``OUTSIDE``, ``NONFINITE``) or a
    physical contact in the scene backend (``CONTACT``).

    Parameters
    ----------
    code : int
        Status code.

    Returns
    -------
    bool
        True for ``10 <= code < 30``.
    """
    return 10 <= int(code) < 30
