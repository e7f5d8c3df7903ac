"""A pass's resume point as rows of the store's progress table, each written when it changed.

A monitor pass commits its resume point (:mod:`bomc_bt.pass_resume`) with every frame.
Written whole, the point of a 50 x 45 m office's pass was 150 KB a frame on average, about
0.8 GB a pass into SQLite's log (a 93 x 90 m floor's 220 KB a frame at the pass's end),
though most of it had not changed since the frame before: the obstacle layer's tiles,
the graph's per-node maps, and the view polygons since the last waypoint, a list that
only grows. So the point is kept as a *shell* row, ``resume/<session>``, with the small
values and the layout of its parts, and one row per part below it:

* a split map (:data:`SPLIT_MAPS`: the obstacle layer's tiles, the random streams, the
  navigator's state, the graph's pass state and its larger maps): a row per member, e.g.
  ``resume/1/graph/last_seen``;
* a split list (:data:`SPLIT_LISTS`: view polygons, looked-at fans and sightings since the
  last waypoint, lists that are only appended to): a row per item, e.g. ``resume/1/fov_since/0``.

A row is written only when its text differs from the one last written, and the rows of
parts no longer in the point are deleted (:data:`~bomc_bt.json_text.DROP`); the caller writes
all of a moment's rows in one transaction and then calls :meth:`ResumeRows.written`, so
the rows on disk are always one moment's point. :func:`load_resume_point` puts it back
together; a shell without ``parts`` is a point saved whole (before the split) and is read
as it is.
"""

from __future__ import annotations

from typing import Any

from bomc_bt.errors import BomcError
from bomc_bt.json_text import DROP, AppendOnlyJSON, EncodedJSON, JSONMemo, dumps, dumps_raw

# paths of the maps stored a row per member, inner ones before the map that holds them
SPLIT_MAPS = ("robot/obstacles/tiles", "robot/rng", "robot/navigation", "graph/extents", "graph/tentative", "graph")
SPLIT_LISTS = ("fov_since", "looked_since", "sighted_since")  # paths of the appended lists stored a row per item


def resume_key(session: int) -> str:
    """The shell row of ``session``'s resume point; its parts' rows lie below it."""
    return f"resume/{session}"


class ResumeRows:
    """The rows of a pass's resume point to write at this moment (module docstring).

    One writer per pass: it remembers the text of each row it wrote, so it must see every
    write of the point (each frame's and each waypoint's)."""

    def __init__(self) -> None:
        self.graph = JSONMemo()  # the graph's pass state, each map entry encoded once
        self._lists: dict[str, AppendOnlyJSON] = {}  # each split list's items' texts, each encoded once
        self._written: dict[str, str] = {}  # the shell's and each map member's row -> text, as last written
        self._counted: dict[str, tuple[list, int]] = {}  # each split list and its rows, as last written
        self._pending: dict[str, str | None] = {}  # the last call's shell and member rows, None: to delete
        self._pending_counts: dict[str, tuple[list, int]] = {}  # and its lists' rows

    def rows(self, session: int, point: dict[str, Any]) -> dict[str, Any]:
        """The progress rows to write for ``point`` (``graph`` encoded with :attr:`graph`;
        the lists the pass's own, appended to in place): the shell, each part whose text
        differs from the last written, and :data:`~bomc_bt.json_text.DROP` for parts gone."""
        shell, prefix = dict(point), resume_key(session)
        texts: dict[str, str] = {}
        layout: dict[str, Any] = {}
        for path in SPLIT_MAPS:
            members = _detach(shell, path)
            if members is not None:
                layout[path] = list(members)
                texts.update((f"{prefix}/{path}/{name}", _text(v)) for name, v in members.items())
        items: dict[str, str | None] = {}
        self._pending_counts = {}
        for path in SPLIT_LISTS:
            layout[path] = self._item_rows(f"{prefix}/{path}", path, shell.pop(path), items)
        shell["parts"] = layout
        texts[prefix] = dumps_raw(shell)
        self._pending = {row: text for row, text in texts.items() if not _same_text(self._written.get(row), text)}
        self._pending.update((row, None) for row in self._written if row not in texts)
        return {row: DROP if text is None else EncodedJSON(text) for row, text in (*self._pending.items(),
                                                                                   *items.items())}

    def written(self) -> None:
        """The rows of the last :meth:`rows` are in the store (call after its transaction)."""
        for row, text in self._pending.items():
            if text is None:
                self._written.pop(row, None)
            else:
                self._written[row] = text
        self._counted.update(self._pending_counts)
        self._pending, self._pending_counts = {}, {}

    def _item_rows(self, row: str, path: str, listed: list, out: dict[str, str | None]) -> int:
        """Put into ``out`` the rows (below ``row``) of the items of list ``path`` not written
        yet: those appended since, or every item of a new list and None for the rows of the
        old one past its end. Returns the list's length."""
        encoded = self._lists.setdefault(path, AppendOnlyJSON()).parts(listed)
        kept, count = self._counted.get(path, (None, 0))
        start = count if kept is listed and count <= len(encoded) else 0
        out.update((f"{row}/{k}", encoded[k]) for k in range(start, len(encoded)))
        out.update((f"{row}/{k}", None) for k in range(len(encoded), count))
        self._pending_counts[path] = (listed, len(encoded))
        return len(encoded)


def load_resume_point(store, session: int) -> Any:
    """``session``'s resume point as :class:`ResumeRows` wrote it (a point saved whole: as
    it is; none saved: None). A part listed in the shell but missing from the store is a
    damaged site: :class:`~bomc_bt.errors.BomcError`."""
    prefix = resume_key(session)
    rows = store.progress_below(prefix)  # one moment's rows, though a pass may be writing
    point = rows.get(prefix)
    if not isinstance(point, dict) or not isinstance(point.get("parts"), dict):
        return point
    parts = point.pop("parts")
    for path in sorted(parts, key=lambda p: p.count("/")):  # a map before the maps split out of it
        layout = parts[path]
        if isinstance(layout, list):
            value: Any = {str(name): _part(store, rows, f"{prefix}/{path}/{name}") for name in layout}
        else:
            value = [_part(store, rows, f"{prefix}/{path}/{k}") for k in range(int(layout))]
        _attach(point, path, value)
    return point


def _part(store, rows: dict[str, Any], row: str) -> Any:
    if row not in rows:
        raise BomcError(f"the pass's resume point lacks its part {row!r}", store.path, "progress")
    return rows[row]


def _text(value: Any) -> str:
    """A part's JSON text (a str is a tile's already encoded text, written as a JSON string)."""
    return dumps_raw(value) if isinstance(value, dict | EncodedJSON) else dumps(value)


def _same_text(old: str | None, new: str) -> bool:
    return old is new or old == new


def _detach(point: dict[str, Any], path: str) -> dict[str, Any] | None:
    """Take the map at ``path`` out of ``point`` (the dicts on the way copied, not changed);
    None, and ``point`` as it was, where no map is there (no robot state, no goal in flight)."""
    *parents, last = path.split("/")
    node = point
    for name in parents:
        child = node.get(name)
        if not isinstance(child, dict):
            return None
        node[name] = child = dict(child)
        node = child
    members = node.get(last)
    if not isinstance(members, dict):
        return None
    del node[last]
    return members


def _attach(point: dict[str, Any], path: str, value: Any) -> None:
    *parents, last = path.split("/")
    node = point
    for name in parents:
        node = node.setdefault(name, {})
    node[last] = value
