"""Command-line entry point: ``oneocean verify [results/]``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _verify(args) -> int:
    from .manifest import verify

    results = Path(args.results)
    manifest = results / "manifest.json"
    if not manifest.is_file():
        print(f"oneocean verify: {manifest}: no manifest (run the workflow first)", file=sys.stderr)
        return 2
    problems = verify(manifest, root=results.resolve().parent)
    for line in problems:
        print(f"MISMATCH {line}")
    if problems:
        print(f"oneocean verify: {len(problems)} artifact(s) do not match {manifest}",
              file=sys.stderr)
        return 1
    import json

    n = len(json.loads(manifest.read_text())["artifacts"])
    print(f"oneocean verify: all {n} artifacts in {manifest} match")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="oneocean", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("verify", help="recompute hashes of every artifact in a results folder")
    p.add_argument("results", nargs="?", default="results",
                   help="results folder holding manifest.json (default: results)")
    p.set_defaults(func=_verify)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
