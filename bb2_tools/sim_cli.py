"""``bb2-sim``: the ROM's maneuvers (:mod:`bb2_sim.cli`) and closed-loop missions (:mod:`bb2_tools.mission_cli`).

``bb2-sim maneuver NAME [options]``, ``bb2-sim mission FILE.yaml [options]`` and ``bb2-sim sea [options]``
(the elevation record of a sea); exit 0 done, 1 the run
diverged / the mission failed, 2 bad input.
"""
from __future__ import annotations

import sys

from bb2_sim.outputs import run_cli
from bb2_sim.cli import _Parser, add_maneuver_parser, add_sea_parser, run_maneuver_cli, run_sea_cli

from bb2_tools.mission_cli import add_mission_parser, run_mission_cli


def build_parser() -> _Parser:
    p = _Parser(prog="bb2-sim", description="BB2 reduced-order model: maneuvers and missions.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    add_maneuver_parser(sub)
    add_mission_parser(sub)
    add_sea_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Exit 0 done, 1 diverged / mission failed, 2 bad input or an OS error (one line), 130 Ctrl-C."""
    return run_cli("bb2-sim", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "maneuver":
        return run_maneuver_cli(args)
    if args.command == "sea":
        return run_sea_cli(args)
    return run_mission_cli(args)


if __name__ == "__main__":
    sys.exit(main())
