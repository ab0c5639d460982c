from oneocean import smk
from oneocean.snapshots import plot_snapshots


def make(s):
    # optional param `episodes`: the rollout cells' episode count, so each row is exactly the
    # episode 0 of that cell (Cell.reset(episodes, seed) row 0)
    episodes = getattr(s.params, "episodes", None)
    plot_snapshots(s.input.grid, s.output.png, tasks=list(s.params.tasks),
                   tier=int(s.params.tier), seed=int(s.params.seed), method=str(s.params.method),
                   episodes=None if episodes is None else int(episodes))


smk.run(snakemake, make)
