"""What the web viewer shows, as versioned JSON sections, for a running mission or a finished site.

The page is a pure function of a handful of *sections* (``tree``, ``blackboard``,
``progress``, ``scene``, ``events``, ``map``, ``site``). :class:`StateStore` keeps the
latest value of each with the version at which it last changed, so the server pushes only
the sections that changed since what a client has seen, and a client that reconnects with
an unknown or stale version (a restarted server: another ``epoch``) gets everything.

The occupancy grid is the one big thing: it never goes into JSON. The store keeps a copy
of the cells and the ``map`` section carries only its version and geometry; the server
encodes the PNG lazily, on its own thread, once per version.

The sections are built in :mod:`bomc_bt.viewer.sections`, sampled from a live mission by
:class:`~bomc_bt.viewer.live.ViewerHook` and read from a finished site by
:class:`~bomc_bt.viewer.site.SiteView`.
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from bomc_bt.grid import OccupancyGrid

Sections = dict[str, Any]


@dataclass
class ViewerParams:
    """Tunables of the viewer (display only: none of them changes what the robot does)."""

    interval_wall_s: float = 0.2  # at most 5 samples per wall second
    map_interval_sim_s: float = 2.0  # the live map is copied at most this often (robot s)
    path_step: float = 0.05  # m the robot must move before the path gets a new point
    max_path_points: int = 4000  # older path points are thinned beyond this
    max_events: int = 200  # newest events kept in the log
    highlight_s: float = 30.0  # robot s an added / moved object stays highlighted
    max_frontier_cells: int = 4000  # frontier cells sent, subsampled evenly beyond this
    blackboard_keys: int = 200  # keys shown
    value_chars: int = 80  # characters of a blackboard value's repr


class StateStore:
    """Thread-safe latest value of every section, each with the version it last changed at."""

    def __init__(self) -> None:
        self.epoch = f"{os.getpid():x}{time.time_ns():x}"  # tells a restarted server from this one
        self._cond = threading.Condition()
        self._version = 0
        self._sections: Sections = {}
        self._changed_at: dict[str, int] = {}
        self._map_cells: np.ndarray | None = None
        self._png: tuple[int, bytes] | None = None
        self._closed = False

    @property
    def version(self) -> int:
        with self._cond:
            return self._version

    def update(self, sections: Sections) -> int:
        """Store the sections whose value differs from the stored one; returns the version."""
        with self._cond:
            changed = [k for k, v in sections.items() if k not in self._sections or self._sections[k] != v]
            if changed:
                self._version += 1
                for key in changed:
                    self._sections[key] = sections[key]
                    self._changed_at[key] = self._version
                self._cond.notify_all()
            return self._version

    def set_map(self, grid: OccupancyGrid) -> None:
        """A new occupancy grid: copy its cells and bump the ``map`` section."""
        cells = np.array(grid.data, dtype=np.int8, copy=True)
        with self._cond:
            if self._map_cells is not None and np.array_equal(self._map_cells, cells):
                return
            self._map_cells = cells
            number = self._sections.get("map", {}).get("number", 0) + 1
        self.update({"map": {
            "number": number, "width": int(grid.width), "height": int(grid.height),
            "resolution": float(grid.resolution), "origin": [float(grid.origin[0]), float(grid.origin[1])],
        }})

    def changes(self, since: int | None) -> tuple[int, Sections, bool]:
        """(version, sections changed after ``since``, full); ``since`` None or ahead of us: all."""
        with self._cond:
            full = since is None or since > self._version
            picked = {k: v for k, v in self._sections.items() if full or self._changed_at[k] > since}
            return self._version, picked, full

    def wait(self, since: int, timeout: float) -> bool:
        """Block until the version passes ``since`` (True) or ``timeout`` wall seconds pass."""
        with self._cond:
            return self._cond.wait_for(lambda: self._closed or self._version > since, timeout)

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        return self._closed

    def map_png(self) -> bytes | None:
        """The current map as a north-up grey PNG (encoded once per map version)."""
        import cv2

        with self._cond:
            cells = self._map_cells
            number = self._sections.get("map", {}).get("number", 0)
            if cells is None:
                return None
            if self._png is not None and self._png[0] == number:
                return self._png[1]
        ok, data = cv2.imencode(".png", map_pixels(cells))
        if not ok:
            raise OSError("cannot encode the map as PNG")
        png = data.tobytes()
        with self._cond:
            self._png = (number, png)
        return png


def map_pixels(cells: np.ndarray) -> np.ndarray:
    """Grey levels as ``render.map_image`` draws them (unknown 205, free 254, occupied 40), north up."""
    img = np.full(cells.shape, 205, dtype=np.uint8)
    img[cells == 0] = 254
    img[cells >= 50] = 40
    return np.ascontiguousarray(np.flipud(img))
