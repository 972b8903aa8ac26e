"""The command line every scene driver shares: ranks, output, seed, deck variables, the
settled-state cache, and how a result is printed."""
from __future__ import annotations

import argparse
import json


def scene_parser(doc: str, seed: int, params: dict, codes: tuple | None = None, hvar: str | None = None,
                 var: str = "deck variable", cache: str | None = None) -> argparse.ArgumentParser:
    """A driver's parser: its scene's parameters (`params`: {name: (default, help[, type])}, the type
    the default's, float for None; --name, with - for _) and the shared options: --np, --out, --seed,
    --var, --json; --code when the scene has several forms (`codes`), --hvar (`hvar`: the hybrid
    twin's variables) and --no-cache, --cache-dir (`cache`: what is cached)."""
    p = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    for name, (default, text, *kind) in params.items():
        kind = kind[0] if kind else float if default is None else type(default)
        p.add_argument(f"--{name.replace('_', '-')}", type=kind, default=default, help=text)
    if codes:
        p.add_argument("--code", choices=sorted(codes), default="lammps", help="code of the run")
    p.add_argument("--np", type=int, default=1, dest="np_", help="MPI ranks (tools/mpirun.sh)")
    p.add_argument("--out", default=None, help="output directory")
    p.add_argument("--seed", type=int, default=seed, help=f"seed of the initial grains (default {seed})")
    p.add_argument("--var", action="append", default=[], metavar="NAME=VALUE", help=f"extra {var}")
    if hvar:
        p.add_argument("--hvar", action="append", default=[], metavar="NAME=VALUE", help=hvar)
    if cache:
        p.add_argument("--no-cache", action="store_true", help=f"rebuild the settled {cache}")
        p.add_argument("--cache-dir", default=None, help="cache directory (default $HYBRID_CACHE)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    return p


def deck_vars(parser: argparse.ArgumentParser, items: list, option: str = "--var") -> dict:
    """The NAME=VALUE items of a repeatable command-line option as deck variables; a malformed
    item is a usage error naming it."""
    variables = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            parser.error(f"{option} {item!r}: expected NAME=VALUE")
        variables[name] = value
    return variables


def parse(parser: argparse.ArgumentParser, argv=None) -> argparse.Namespace:
    """parse_args, with --var (and --hvar) turned into dicts (a.var, a.hvar)."""
    a = parser.parse_args(argv)
    a.var = deck_vars(parser, a.var)
    if hasattr(a, "hvar"):
        a.hvar = deck_vars(parser, a.hvar, "--hvar")
    return a


def print_result(res, as_json: bool, **derived) -> None:
    """A scene driver's result: its fields (and derived figures) as JSON, or its LAMMPS log
    excerpt and summary."""
    if as_json:
        print(json.dumps(dict(res.__dict__, **derived), indent=1, default=str))
    else:
        print(res.log)
        print(res.summary())
