"""``bomc objects | changes | export | publish | edit``: the operator's tools on a finished site.

The first four only read the site (:mod:`bomc_bt.site.query`, no lock, nothing written
into it); ``edit`` takes the writer's lock (:mod:`bomc_bt.site.edits`). Bad input is a
:class:`BomcError`: one line, exit 2 (cli.main prints it).
"""

from __future__ import annotations

import argparse
import math
import sys

from bomc_bt.errors import BomcError

COMMANDS = ("objects", "changes", "export", "publish", "edit")


def add_parsers(sub, parser_class: type[argparse.ArgumentParser]) -> None:
    """Register the commands on ``bomc``'s subparsers (``parser_class``: its one-line errors)."""
    def site_arg(p) -> None:
        p.add_argument("site", metavar="SITE", help="site directory")
        p.add_argument("--config", action="append", default=[], metavar="FILE",
                       help="config file for the association distances (changes) and the like")

    o = sub.add_parser("objects", help="the objects of a finished site (read-only)")
    site_arg(o)
    o.add_argument("--session", type=_int("--session", 1), default=None,
                   help="as the map stood at the end of session N (default: now)")
    o.add_argument("--category", default=None, help="only this category")
    o.add_argument("--near", type=_point, default=None, metavar="X,Y", help="only objects near this map point (m)")
    o.add_argument("--radius", type=_float("--radius"), default=None, metavar="R",
                   help="with --near: within R m (default 2)")
    o.add_argument("--format", choices=("table", "json", "csv", "geojson"), default="table")

    c = sub.add_parser("changes", help="net changes per pass, with evidence (read-only)")
    site_arg(c)
    c.add_argument("--since", type=_int("--since", 0), default=None, help="passes after session N")
    c.add_argument("--until", type=_int("--until", 1), default=None, help="passes up to session M")
    c.add_argument("--format", choices=("table", "json", "csv"), default="table")

    x = sub.add_parser("export", help="the map as PNG + world file, the objects as GeoJSON / CSV / JSON")
    site_arg(x)
    x.add_argument("--out", required=True, help="folder to write into (created if missing)")
    x.add_argument("--session", type=_int("--session", 1), default=None)

    p = sub.add_parser("publish", help="latch the site's map and objects on a running roscore (RViz)")
    site_arg(p)
    p.add_argument("--session", type=_int("--session", 1), default=None)
    p.add_argument("--map-topic", default="/bomc/site_map")
    p.add_argument("--objects-topic", default="/bomc/site_objects")
    p.add_argument("--frame", default="map", help="frame_id of the map and the markers")
    p.add_argument("--duration", type=_float("--duration", allow_zero=True), default=0.0,
                   help="seconds to stay up (default 0: until Ctrl-C)")

    e = sub.add_parser("edit", help="correct the map: relabel, delete, restore or annotate a node")
    e.add_argument("site", metavar="SITE", help="site directory")
    actions = e.add_subparsers(dest="action", required=True, parser_class=parser_class)
    for name, helptext, value in (("relabel", "give node ID the category CATEGORY", "CATEGORY"),
                                  ("delete", "take node ID off the map (a false detection)", None),
                                  ("restore", "bring back node ID (deleted, or removed by a pass)", None),
                                  ("note", "attach TEXT to node ID", "TEXT")):
        a = actions.add_parser(name, help=helptext)
        a.add_argument("node_id", metavar="ID")
        if value:
            a.add_argument("value", metavar=value, nargs="+", help="words are joined by single spaces")


def run(args) -> int:
    """Run one of :data:`COMMANDS` (parsed by :func:`add_parsers`)."""
    if args.command == "edit":
        from bomc_bt.site.edits import edit_site

        words = getattr(args, "value", None)
        print(edit_site(args.site, args.action, args.node_id, None if words is None else " ".join(words)).message)
        return 0
    from bomc_bt.run import build_config

    association = build_config(args.config).association
    if args.command == "objects":
        return _objects(args, association)
    if args.command == "changes":
        from bomc_bt.site.formats import format_changes
        from bomc_bt.site.query import open_site

        with open_site(args.site, association) as site:
            sys.stdout.write(format_changes(site.changes(args.since, args.until), args.format))
        return 0
    if args.command == "export":
        from bomc_bt.site.export import export_site

        for path in export_site(args.site, args.out, args.session, association):
            print(path)
        return 0
    from bomc_bt.ros.site_publish import PublishTopics, publish_site

    topics = PublishTopics(args.map_topic, args.objects_topic, args.frame)
    return publish_site(args.site, topics, args.session, args.duration, association)


def _objects(args, association) -> int:
    from pathlib import Path

    from bomc_bt.site.formats import format_objects
    from bomc_bt.site.query import open_site

    if args.radius is not None and args.near is None:
        raise BomcError("--radius needs --near X,Y", None, "--radius")
    with open_site(args.site, association) as site:
        objects = site.objects(args.session, args.category, args.near, 2.0 if args.radius is None else args.radius)
    header = {"site": Path(args.site).resolve().name, "session": args.session}
    sys.stdout.write(format_objects(objects, args.format, header))
    return 0


def _int(option: str, minimum: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option} must be a whole number, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{option} must be >= {minimum}, got {value}")
        return value
    return parse


def _float(option: str, allow_zero: bool = False):
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option} must be a number, got {text!r}") from None
        if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero) or value > 1e6:
            raise argparse.ArgumentTypeError(f"{option} must be a positive number up to 1e6, got {text!r}")
        return value
    return parse


def _point(text: str) -> tuple[float, float]:
    parts = text.split(",")
    try:
        x, y = (float(v) for v in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--near must be X,Y in metres, got {text!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise argparse.ArgumentTypeError(f"--near must be finite, got {text!r}")
    return x, y
