"""The pass timeline file: ``sessions/<n>/timeline.jsonl``, append-only JSON Lines.

Why JSON Lines, appended: a pass writes its timeline while it runs, and a kill at any
moment must lose at most the last few records, never what came before nor another
session's file (each pass owns its own file; nothing else is ever rewritten). A torn last
line is the only damage a crash can do, and :func:`read_timeline` skips it. Lines are
written in a buffer and flushed at most every ``flush_period`` seconds of wall time (the
cost of recording stays far below the pass's own work), and fsynced when the pass ends.

One record per line, compact keys (``k`` the kind, ``t`` the robot time in s)::

    {"k":"head","v":1,"session":2,"t":0.0,"resume":false}   a pass (or a resumed pass) starts
    {"k":"tree","t":0.0,"n":[[name,kind,type,parent],...]}  the tree's nodes, depth first
    {"k":"st","t":1.2,"c":[[i,"r","feedback"],...]}         nodes whose status or feedback changed
    {"k":"pose","t":1.5,"p":[x,y,yaw],"g":[x,y,yaw]}        estimated pose (null: not localized), true pose (sim)
    {"k":"frame","t":1.6,"n":12,"wh":[w,h],"d":[[cat,x0,y0,x1,y1,score],...],"o":[[cat,x,y],...]}
                                                            a frame's detections (pixel boxes) and their map points
    {"k":"ev","t":1.6,"e":[[kind,id,cat,x,y,fx,fy],...]}    graph events (fx, fy: where a moved node was)

Events are the pass's association's (``Perception.events``); the ``updated`` rows the store
adds when a session ends, to square its history with the nodes, are bookkeeping and not in
the timeline. Statuses are one letter: ``s`` success, ``f`` failure, ``r`` running, ``i``
invalid.

A resumed pass appends a new ``head``; the records of the killed run from the resume time
on are dropped on reading, but for the frame and events committed at that time (the
resumed pass goes on from its last commit, so robot time repeats). A ``head`` that is not
a resume starts the file's content afresh (a pass killed before it opened its session runs
again from the start).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bomc_bt.errors import BomcError

FILE_NAME = "timeline.jsonl"
VERSION = 1
KINDS = ("head", "tree", "st", "pose", "frame", "ev")
MAX_BYTES = 512 * 1024 * 1024  # [count] bytes: a larger file is not a timeline this code wrote


class TimelineWriter:
    """Appends records to one session's timeline file; flushed on a wall-clock period."""

    def __init__(self, path: Path, flush_period: float = 1.0, wall_clock: Callable[[], float] = time.monotonic):
        self.path = Path(path)
        self.flush_period = flush_period
        self.wall_clock = wall_clock
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "ab")  # noqa: SIM115 - kept open for the pass
        if self._file.tell() > 0 and not _ends_with_newline(self.path):
            self._file.write(b"\n")  # a killed run's torn last line stays a line of its own
        self._last_flush = wall_clock()
        self.records = 0
        self._encode = json.JSONEncoder(separators=(",", ":"), allow_nan=False).encode

    def write(self, record: dict[str, Any]) -> None:
        self._file.write(self._encode(record).encode() + b"\n")
        self.records += 1
        now = self.wall_clock()
        if now - self._last_flush >= self.flush_period:
            self._file.flush()
            self._last_flush = now

    def close(self) -> None:
        """Flush and fsync; safe to call twice."""
        if not self._file.closed:
            self._file.flush()
            os.fsync(self._file.fileno())
            self._file.close()

    @property
    def closed(self) -> bool:
        return self._file.closed


@dataclass
class Timeline:
    """A pass's timeline as read back: records by kind, each list in time order."""

    session: int
    tree: list[list[Any]] = field(default_factory=list)  # the last tree record's nodes
    status: list[dict[str, Any]] = field(default_factory=list)
    poses: list[dict[str, Any]] = field(default_factory=list)
    frames: list[dict[str, Any]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    start: float = 0.0  # [s] robot time of the first record
    end: float = 0.0  # [s] robot time of the last record
    resumes: int = 0  # how many times the pass was resumed
    skipped: int = 0  # lines that could not be read (a torn last line after a kill)

    def to_json(self) -> dict[str, Any]:
        return {"session": self.session, "start": self.start, "end": self.end, "resumes": self.resumes,
                "tree": self.tree, "status": self.status, "poses": self.poses, "frames": self.frames,
                "events": self.events, "skipped": self.skipped}


def read_timeline(path: Path, session: int) -> Timeline:
    """The timeline in ``path``; BomcError when it is missing or not a timeline file."""
    path = Path(path)
    try:
        if path.stat().st_size > MAX_BYTES:
            raise BomcError(f"too large for a timeline ({path.stat().st_size} bytes)", path)
        raw = path.read_bytes()
    except FileNotFoundError:
        raise BomcError(f"no timeline recorded for session {session}", path) from None
    except OSError as exc:
        raise BomcError(f"unreadable timeline ({exc.strerror})", path) from None
    records, skipped = _records(raw)
    if not records or records[0].get("k") != "head":
        raise BomcError("not a timeline (the first record is not a head)", path)
    timeline = Timeline(session, skipped=skipped)
    records = _drop_replayed(records)
    for record in records:
        _add(timeline, record)
    times = [r["t"] for r in records]
    timeline.start, timeline.end = min(times), max(times)
    return timeline


def _records(raw: bytes) -> tuple[list[dict[str, Any]], int]:
    """Decoded records with a number ``t`` and a known kind; how many lines were not."""
    out, skipped = [], 0
    for line in raw.split(b"\n"):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except ValueError:
            skipped += 1
            continue
        t = record.get("t") if isinstance(record, dict) else None
        if record.get("k") not in KINDS or not isinstance(t, (int, float)) or isinstance(t, bool):
            skipped += 1
            continue
        out.append(record)
    return out, skipped


def _drop_replayed(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each resumed pass cuts off what the killed run recorded after its resume time; a
    pass that starts afresh (killed before it opened its session) replaces the run before."""
    kept: list[dict[str, Any]] = []
    for record in records:
        if record["k"] == "head" and kept:
            kept = [r for r in kept if _before_resume(r, record["t"])] if record.get("resume") else []
        kept.append(record)
    return kept


def _before_resume(record: dict[str, Any], t: float) -> bool:
    """Whether the killed run's ``record`` stands before a pass resumed at robot time ``t``.

    The resumed pass starts from its last commit, at ``t``: the frame committed then and its
    events stay (the resumed pass does not see them again), the tree and the pose at ``t``
    are written again by its first tick.
    """
    return record["t"] < t or record["k"] in ("head", "tree") or (record["t"] == t and record["k"] in ("frame", "ev"))


def _add(timeline: Timeline, record: dict[str, Any]) -> None:
    kind = record["k"]
    if kind == "head":
        timeline.resumes += bool(record.get("resume"))
    elif kind == "tree" and isinstance(record.get("n"), list):
        timeline.tree = record["n"]
    elif kind == "st" and isinstance(record.get("c"), list):
        timeline.status.append({"t": record["t"], "c": record["c"]})
    elif kind == "pose":
        timeline.poses.append({"t": record["t"], "p": record.get("p"), "g": record.get("g")})
    elif kind == "frame":
        timeline.frames.append({"t": record["t"], "n": record.get("n"), "wh": record.get("wh"),
                                "d": record.get("d") or [], "o": record.get("o") or []})
    elif kind == "ev" and isinstance(record.get("e"), list):
        timeline.events.append({"t": record["t"], "e": record["e"]})


def _ends_with_newline(path: Path) -> bool:
    with open(path, "rb") as f:
        f.seek(-1, os.SEEK_END)
        return f.read(1) == b"\n"


def timeline_path(session_dir: Path) -> Path:
    return Path(session_dir) / FILE_NAME
