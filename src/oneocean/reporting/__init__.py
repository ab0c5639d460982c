"""Reporting: what the workflow makes of the cells.

* :mod:`.tables` -- the paper's tables from cell files (rates with Wilson intervals, the
  ladder checks), :mod:`.latex` their LaTeX, :mod:`.ladder` the cells' loading and the
  ladder's checks, :mod:`.planning` the planning suite, :mod:`.ablations` the information and
  stressor ablations, :mod:`.scene_tables` the scene backend's tables;
* :mod:`.figures`, :mod:`.snapshots` and :mod:`.render` -- the figures.

Each takes cell files or frames and returns frames or files; none runs an episode.
"""
