from oneocean.pipeline import smk
from oneocean.reporting.snapshots import plot_snapshots


def make(s):
    # `episodes`: the rollout cells' episode count, so each row is exactly episode `episode`
    # of that cell (Cell.reset(episodes, seed) row `episode`)
    plot_snapshots(s.input.grid, s.output.png, tasks=list(s.params.tasks),
                   tier=int(s.params.tier), seed=int(s.params.seed), method=str(s.params.method),
                   episode=int(s.params.episode), episodes=int(s.params.episodes),
                   dynamics=str(s.params.dynamics))


smk.run(snakemake, make)
