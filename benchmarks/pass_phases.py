"""Where a monitor pass's robot time and path went, phase by phase, read from its timeline.

A pass drives its coverage tour (Visit Waypoints), then the gap viewpoints (Cover Gaps)
and the refresh stops and last looks (Refresh Stale), and turns on the spot at some stops (Look Around).
The session's ``timeline.jsonl`` (what ``bomc view --replay`` plays) records every tree
node's status and the robot's pose at each tick; this script attributes each pose step to
the phase running at that tick and prints one row per phase and per session given:

    python benchmarks/pass_phases.py SITE/sessions/1/timeline.jsonl SITE/sessions/2/timeline.jsonl
    python benchmarks/pass_phases.py SITE          # every session of a site, in order

Path is summed over the recorded poses (one per tick), so it reads a little shorter than
the report's odometer on curves.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

# the gap and refresh phases reuse the visit loop's subtree (Look Around included), so
# they are asked first; Look Around is then the turning at the coverage tour's stops
PHASES = ("Visit Gap Viewpoints", "Visit Refresh Stops", "Visit Last Looks", "Look Around", "Visit Waypoints")
LABELS = {"Visit Waypoints": "coverage tour", "Visit Gap Viewpoints": "gap viewpoints",
          "Visit Refresh Stops": "refresh stops", "Visit Last Looks": "last looks",
          "Look Around": "look around at tour stops"}


def phases(timeline: Path) -> dict[str, list[float]]:
    """{phase: [metres, seconds]} of one session's timeline."""
    names: list[str] = []
    running: dict[str, str] = {}
    out: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0])
    last, last_t = None, 0.0
    with open(timeline) as f:
        for line in f:
            rec = json.loads(line)
            if rec["k"] == "tree":
                names = [n[0] for n in rec["n"]]
            elif rec["k"] == "st":
                running.update({names[i]: s for i, s, _ in rec["c"]})
            elif rec["k"] == "pose" and (rec.get("g") or rec.get("p")) is not None:
                xy = rec.get("g") or rec.get("p")
                phase = next((p for p in PHASES if running.get(p) == "r"), "other")
                if last is not None:
                    out[phase][0] += math.hypot(xy[0] - last[0], xy[1] - last[1])
                    out[phase][1] += rec["t"] - last_t
                last, last_t = xy, rec["t"]
    return dict(out)


def timelines(paths: list[Path]) -> list[Path]:
    """Each path as given, or for a site folder its sessions' timelines in session order."""
    out: list[Path] = []
    for path in paths:
        if path.is_dir():
            found = sorted(path.glob("sessions/*/timeline.jsonl"), key=lambda p: int(p.parent.name)
                           if p.parent.name.isdigit() else 0)
            if not found:
                raise ValueError(f"{path}: no sessions/N/timeline.jsonl in this folder (a site?)")
            out += found
        elif path.is_file():
            out.append(path)
        else:
            raise ValueError(f"{path}: no such timeline file or site folder")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Where a monitor pass's robot time and path went, phase by phase.")
    ap.add_argument("paths", nargs="+", type=Path, help="timeline.jsonl files, or site folders (all their sessions)")
    args = ap.parse_args(argv)
    try:
        paths = timelines(args.paths)
    except ValueError as e:
        print(e, file=sys.stderr)
        return 2
    print(f"{'timeline':40} {'phase':26} {'path m':>8} {'robot s':>8} {'share of time':>13}")
    for path in paths:
        rows = phases(path)
        total = sum(s for _, s in rows.values()) or 1.0
        for phase in ("Visit Waypoints", "Look Around", *PHASES[:3], "other"):
            if phase in rows:
                m, s = rows[phase]
                print(f"{str(path)[-40:]:40} {LABELS.get(phase, phase):26} {m:8.0f} {s:8.0f} {s / total:13.1%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
