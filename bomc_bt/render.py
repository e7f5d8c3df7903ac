"""Pictures of a site: the occupancy map with the object graph drawn on it (PNG)."""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from pathlib import Path

import cv2
import numpy as np

from bomc_bt.atomic import atomic_write
from bomc_bt.grid import OccupancyGrid


def category_colour(category: str) -> tuple[int, int, int]:
    """A stable, saturated BGR colour per category name (open vocabulary: no fixed table)."""
    h = int(hashlib.md5(category.encode()).hexdigest()[:4], 16) % 180
    hsv = np.uint8([[[h, 200, 220]]])
    b, g, r = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0]
    return int(b), int(g), int(r)


def map_image(grid: OccupancyGrid, min_size: int = 900) -> tuple[np.ndarray, float]:
    """The grid as a BGR image (north up) and the pixels-per-cell scale used."""
    img = np.full(grid.data.shape, 205, dtype=np.uint8)
    img[grid.data == 0] = 254
    img[grid.data >= 50] = 40
    scale = max(1.0, min_size / max(grid.width, grid.height))
    img = cv2.resize(np.flipud(img), None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR), scale


def to_pixel(grid: OccupancyGrid, scale: float, x: float, y: float) -> tuple[int, int]:
    col = (x - grid.origin[0]) / grid.resolution
    row = grid.height - (y - grid.origin[1]) / grid.resolution
    return int(round(col * scale)), int(round(row * scale))


def render_semantic_map(grid: OccupancyGrid, nodes: Iterable, removed: Iterable = (), path: np.ndarray | None = None,
                        waypoints: Iterable = (), title: str = "") -> np.ndarray:
    """Occupancy map + nodes coloured by category with ids; removed nodes crossed out in red."""
    img, scale = map_image(grid)
    if path is not None and len(path) > 1:
        pts = np.array([to_pixel(grid, scale, x, y) for x, y in path[:, :2]], dtype=np.int32)
        cv2.polylines(img, [pts], False, (200, 160, 60), 1, cv2.LINE_AA)
    for wp in waypoints:
        cv2.circle(img, to_pixel(grid, scale, wp.x, wp.y), 4, (160, 110, 30), 1, cv2.LINE_AA)
    radius = max(4, int(0.2 / grid.resolution * scale))
    for node in removed:
        p = to_pixel(grid, scale, float(node.position[0]), float(node.position[1]))
        cv2.drawMarker(img, p, (40, 40, 230), cv2.MARKER_TILTED_CROSS, radius * 2, 2, cv2.LINE_AA)
    categories: dict[str, tuple[int, int, int]] = {}
    for node in nodes:
        colour = categories.setdefault(node.category, category_colour(node.category))
        p = to_pixel(grid, scale, float(node.position[0]), float(node.position[1]))
        cv2.circle(img, p, radius, colour, -1, cv2.LINE_AA)
        cv2.circle(img, p, radius, (30, 30, 30), 1, cv2.LINE_AA)
        cv2.putText(img, str(node.id), (p[0] + radius + 1, p[1] - radius), cv2.FONT_HERSHEY_SIMPLEX,
                    0.35, (20, 20, 20), 1, cv2.LINE_AA)
    _legend(img, categories, title)
    return img


def _legend(img: np.ndarray, categories: dict[str, tuple[int, int, int]], title: str) -> None:
    """Title and one line per category at the top left, on a light panel: drawn straight onto
    the map, the words ran into the walls and the node ids under them."""
    font, size = cv2.FONT_HERSHEY_SIMPLEX, 0.45
    lines = ([title] if title else []) + sorted(categories)
    if not lines:
        return
    width = max(cv2.getTextSize(text, font, 0.5 if text == title else size, 1)[0][0] for text in lines)
    x1, y1 = min(img.shape[1], 26 + width + 8), min(img.shape[0], 6 + 18 * len(lines) + (2 if title else 0) + 4)
    panel = img[0:y1, 0:x1]
    panel[:] = (0.15 * panel + 0.85 * 255).astype(np.uint8)
    cv2.rectangle(img, (0, 0), (x1 - 1, y1 - 1), (150, 150, 150), 1)
    y = 18
    if title:
        cv2.putText(img, title, (8, y), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        y += 20
    for name, colour in sorted(categories.items()):
        cv2.circle(img, (14, y - 4), 6, colour, -1, cv2.LINE_AA)
        cv2.putText(img, name, (26, y), font, size, (0, 0, 0), 1, cv2.LINE_AA)
        y += 18


def save_png(img: np.ndarray, path: Path) -> None:
    ok, data = cv2.imencode(".png", img)
    if not ok:
        raise OSError(f"cannot encode {path}")
    atomic_write(path, data.tobytes())
