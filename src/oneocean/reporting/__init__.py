"""Reporting: what the workflow makes of the cells, one module per concern.

* :mod:`.cells` -- cell files into rows: the reader, forcing conditions, per-cell rates, macros.
* :mod:`.stats` -- the 95 % intervals (Wilson, seeded bootstraps) and the macro aggregates.
* :mod:`.tables` -- the paper's tables (Tables II, III, V, difficulty, forcing ablation).
* :mod:`.latex` -- the booktabs writer, and compiling the paper and tables to PDF.
* :mod:`.ladder` -- the ladder's protocol checks and its Markdown (``ladder.md``, the README).
* :mod:`.ablations` -- the information-ablation and tier-stressor tables.
* :mod:`.planning` -- the planning suite's tables (Tables IV and VI).
* :mod:`.scene_tables` -- the scene backend's tables (Table VII, core vs scene).
* :mod:`.figures` -- the paper's result figures (Figs. 3, 4, 6, 7, RL curves), in one style.
* :mod:`.snapshots` -- Fig. 5: one-episode snapshots over the bathymetry.
* :mod:`.render` -- the envs' top-down ``rgb_array`` picture of an episode.

Each takes cell files or frames and returns frames or files; none runs an episode but
:mod:`.snapshots`, which runs the one episode it draws.
"""
