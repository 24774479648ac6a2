"""`aerobench` command line: a thin layer that parses arguments and calls the library.

One module per family of commands; each adds its sub-parsers and runs them. User mistakes (unknown names, bad
numbers) end in one line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys

from .common import Parser, UserError, quiet_offline_environment
from .data import add_dataset, add_generate
from .demo import add_demo
from .evaluation import add_compare, add_conditions, add_eval, add_leaderboard, add_plan, add_publish, add_summarize
from .flight import add_fly, add_render
from .training import add_pi_init, add_train

__all__ = ["UserError", "build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="aerobench", description="aerobench: aerial manipulation benchmark (see README.md)")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    add_fly(sub)
    add_demo(sub)
    add_render(sub)
    add_generate(sub)
    add_dataset(sub)
    add_eval(sub)
    add_conditions(sub)
    add_train(sub)
    add_pi_init(sub)
    add_summarize(sub)
    add_compare(sub)
    add_plan(sub)
    add_leaderboard(sub)
    add_publish(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    quiet_offline_environment()
    try:
        return args.func(args)
    except UserError as e:
        print(f"aerobench {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"aerobench {args.command}: interrupted; run the same command again to continue", file=sys.stderr)
        return 130
