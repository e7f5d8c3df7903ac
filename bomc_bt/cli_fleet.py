"""``bomc sync`` and ``bomc pull``: a site to and from the central PostgreSQL store (bomc_bt.central).

The connection string is ``--to`` / ``--from``, else ``$BOMC_CENTRAL``, else libpq's
``PG*`` variables; never a file in the repository. Both print one line and exit 0, or
one ``bomc: error:`` line and exit 2 (an unreachable database included).
"""

from __future__ import annotations

import argparse

COMMANDS = ("sync", "pull")


def add_fleet_commands(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("sync", help="push what is new in a site to the central PostgreSQL store")
    s.add_argument("site", help="site directory")
    s.add_argument("--to", default=None, metavar="URL", help="postgresql://... (default: $BOMC_CENTRAL or PG* vars)")
    s.add_argument("--building", default=None, help="the site's building (first sync; default: the folder's name)")
    s.add_argument("--floor", default=None, help="the site's floor (first sync; default: 1)")
    s.add_argument("--robot", default=None, help="this robot's name (first sync; default: the host name)")
    s.add_argument("--config", action="append", default=[], metavar="FILE")

    p = sub.add_parser("pull", help="make or update a local site from the central store (the next pass's robot)")
    p.add_argument("site", help="site directory to create or bring up to date")
    p.add_argument("--from", dest="source", default=None, metavar="URL",
                   help="postgresql://... (default: $BOMC_CENTRAL or PG* vars)")
    p.add_argument("--building", required=True)
    p.add_argument("--floor", required=True)
    p.add_argument("--robot", default=None, help="this robot's name (default: the host name)")
    p.add_argument("--config", action="append", default=[], metavar="FILE")


def run_fleet_command(args: argparse.Namespace) -> int:
    from bomc_bt.central.connection import resolve
    from bomc_bt.config import load_config

    timeout = load_config(args.config).central.connect_timeout
    if args.command == "sync":
        from bomc_bt.central.sync import sync_site

        result = sync_site(args.site, resolve(args.to, "--to"), building=args.building, floor=args.floor,
                           robot=args.robot, timeout=timeout)
        print(result.line())
        return 0
    from bomc_bt.central.pull import pull_site

    print(pull_site(args.site, resolve(args.source, "--from"), args.building, args.floor, args.robot, timeout))
    return 0
