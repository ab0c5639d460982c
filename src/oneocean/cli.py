"""Command-line entry point: ``oneocean verify [results/]``, ``oneocean evaluate ...``,
``oneocean ladder-readme <region> ...``."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from .vocab import EVALUATION_SEED


def _verify(args) -> int:
    """Verify every region's manifest in ``results/manifest/`` (or one manifest file): one
    ``MISMATCH <path>: <what is wrong>`` line per bad artifact, every artifact checked; exit
    status 1 if any artifact (or manifest) is bad, 2 if there is no manifest."""
    import json

    from .errors import DataError
    from .pipeline.manifest import verify

    target = Path(args.results)
    if target.is_file():
        manifests, results = [target], target.resolve().parents[1]
    else:
        results = target
        manifests = sorted((results / "manifest").glob("*.json"))
    if not manifests:
        print(f"oneocean verify: {target}: no manifest in {target / 'manifest'} (run the "
              "workflow first)", file=sys.stderr)
        return 2
    bad = 0
    for manifest in manifests:
        try:
            problems = verify(manifest, root=results.resolve().parent)
        except DataError as exc:    # the manifest itself is unreadable: the others still run
            bad += 1
            print(f"oneocean verify: {exc}", file=sys.stderr)
            continue
        for line in problems:
            print(f"MISMATCH {line}")
        if problems:
            bad += 1
            print(f"oneocean verify: {len(problems)} artifact(s) do not match {manifest}",
                  file=sys.stderr)
            continue
        n = len(json.loads(manifest.read_text())["artifacts"])
        print(f"oneocean verify: all {n} artifacts in {manifest} match")
    return 1 if bad else 0


def _os_error(exc: OSError) -> str:
    """One line for an OSError: the file and the system's reason."""
    where = exc.filename if exc.filename is not None else ""
    reason = exc.strerror or str(exc)
    return f"{where}: {reason}" if where else reason


def _check_out(out) -> str | None:
    """Why ``--out`` cannot be written (checked before the run), or None."""
    path = Path(out)
    if path.is_dir():
        return f"--out {out}: is a folder; give the output Parquet file's path"
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        return f"--out {out}: {parent} is not a folder"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"--out {out}: cannot write in {parent} (permission denied)"
    return None


def _evaluate(args) -> int:
    """Every expected error (bad input, a missing or unreadable file, a bad policy spec) is
    one line on stderr and exit status 2; errors raised inside the policy keep their
    traceback (they are the policy's own)."""
    from .errors import OneOceanError

    def fail(message: str) -> int:
        print(f"oneocean evaluate: {message}", file=sys.stderr)
        return 2

    problem = _check_out(args.out)
    if problem:
        return fail(problem)
    try:
        from .evaluate import evaluate_to_file

        scene = None
        if args.scene is not None:
            from .backends.mujoco.store import load_scene

            scene = load_scene(args.scene)
        entry = evaluate_to_file(args.policy, args.out, args.task, args.tier,
                                 None if scene is not None else args.grid,
                                 name=args.name, episodes=args.episodes, seed=args.seed,
                                 dynamics=args.dynamics, n_agents=args.n_agents,
                                 currents=not args.currents_off, backend=args.backend,
                                 scene=scene, current_gain=args.current_gain,
                                 tide=(None if args.tide is None else
                                       {"amplitude_ms": args.tide[0],
                                        "period_s": args.tide[1]}),
                                 obs_mode=args.obs_mode, action_mode=args.action_mode)
    except OneOceanError as exc:
        return fail(str(exc))
    except OSError as exc:
        return fail(_os_error(exc))
    import pandas as pd

    df = pd.read_parquet(args.out)
    print(f"{args.task} tier {args.tier} {df['method'].iloc[0]}: SR {df['success'].mean():.1%} "
          f"over {len(df)} episodes, mean {df.attrs.get('primary', 'primary')} "
          f"{df['primary'].mean():.4g}; wrote {entry['path']}")
    return 0


def _ladder_readme(args) -> int:
    from .errors import ConfigError
    from .reporting.ladder import splice_readme

    try:
        for region in args.regions:
            changed = splice_readme(args.readme, Path("results/tables") / region / "ladder.md",
                                    region)
            print(f"oneocean ladder-readme: {region}: "
                  f"{'updated' if changed else 'unchanged'} in {args.readme}")
    except ConfigError as exc:
        print(f"oneocean ladder-readme: {exc}", file=sys.stderr)
        return 2
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``oneocean`` command's parser (the docs' CLI reference is rendered from it).

    Returns
    -------
    argparse.ArgumentParser
        The parser; each subcommand's ``func`` default is its handler.
    """
    parser = argparse.ArgumentParser(prog="oneocean", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("verify", help="recompute hashes of every artifact in a results folder")
    p.add_argument("results", nargs="?", default="results",
                   help="results folder (every region's manifest in results/manifest/) or "
                        "one manifest file (default: results)")
    p.set_defaults(func=_verify)
    p = sub.add_parser("evaluate", help="score your own policy (module:callable) on a cell "
                       "and write the same Parquet table as the workflow")
    p.add_argument("--task", required=True, help="task id, e.g. G2G (any registered task)")
    p.add_argument("--tier", type=int, required=True, help="tier: 1, 2 or 3")
    p.add_argument("--policy", required=True, help="module:callable, obs (E,N,D) -> (E,N,3)")
    p.add_argument("--grid", default=None,
                   help="grid export (.npz) or region config (.yaml; synthetic or local-file "
                        "sources); default: the default region's grid, built into the cache "
                        "($ONEOCEAN_CACHE_DIR or ~/.cache/oneocean) on first use")
    p.add_argument("--out", required=True, help="output Parquet path")
    p.add_argument("--name", default=None, help="method name in the table (default: callable)")
    p.add_argument("--episodes", type=int, default=50, help="number of episodes (default 50)")
    p.add_argument("--seed", type=int, default=EVALUATION_SEED,
                   help=f"evaluation seed (default {EVALUATION_SEED}, held out from calibration)")
    p.add_argument("--dynamics", default="6dof",
                   help="vehicle model: kinematic, 3dof, 4dof or 6dof (default 6dof)")
    p.add_argument("--n-agents", type=int, default=None,
                   help="team size (default: the task's own, within its range)")
    p.add_argument("--currents-off", action="store_true", help="the currents-off ablation")
    p.add_argument("--current-gain", type=float, default=1.0,
                   help="gain on the data currents u, v (default 1: the data as they are)")
    p.add_argument("--tide", type=float, nargs=2, default=None,
                   metavar=("AMPLITUDE_MS", "PERIOD_S"),
                   help="a synthetic tide term, e.g. --tide 0.3 44712 (M2)")
    p.add_argument("--obs-mode", choices=("raw", "normalized"), default=None,
                   help="the observation view the policy gets (default: the policy's own "
                        "obs_mode attribute, else raw)")
    p.add_argument("--action-mode", choices=("velocity", "normalized"), default=None,
                   help="how the policy's actions are read (default: the policy's own "
                        "action_mode attribute, else velocity in m/s)")
    p.add_argument("--backend", choices=("core", "mujoco"), default="core",
                   help="what moves the agents (mujoco needs --scene)")
    p.add_argument("--scene", default=None,
                   help="a scene's scene.json (results/scenes/<region>/<variant>/<scene>/): "
                        "run in that scene (its grid and scene tiers; --grid is ignored)")
    p.set_defaults(func=_evaluate)
    p = sub.add_parser("ladder-readme", help="copy the workflow's ladder tables "
                       "(results/tables/<region>/ladder.md) into the ladder blocks of the README "
                       "(or of docs/results.md, with --readme)")
    p.add_argument("regions", nargs="+", help="region names, e.g. synthetic_coast")
    p.add_argument("--readme", default="README.md",
                   help="the Markdown file holding the ladder blocks (default README.md)")
    p.set_defaults(func=_ladder_readme)
    return parser


def main(argv=None) -> int:
    """Run the ``oneocean`` command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: the process's command line).

    Returns
    -------
    int
        The exit status (0 on success).
    """
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
