"""``bomc export``: the site's map and objects as files other tools read.

Into an output folder (never into the site, which is only read):

* ``map.png`` -- the saved occupancy map as map_server draws it (free 254, occupied 0,
  unknown 205; north = +y up), and ``map.pgw``, its ESRI world file: six lines, the pixel
  size in x, two rotations (0), the pixel size in y (negative: rows go down), and the
  map-frame x, y of the *centre* of the top-left pixel. A GIS places the PNG and the
  GeoJSON (same map-frame metres) on top of each other.
* ``objects.geojson``, ``objects.csv``, ``objects.json`` -- :meth:`SiteReader.objects`
  (now, or at the end of a session) in the formats of :mod:`bomc_bt.site.formats`.

Each file is written atomically; a failed export leaves no half-written file.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from bomc_bt.atomic import atomic_write
from bomc_bt.errors import BomcError
from bomc_bt.graph import AssociationParams
from bomc_bt.grid import FREE, PGM_FREE, PGM_OCCUPIED, PGM_UNKNOWN, OccupancyGrid, load_map
from bomc_bt.site.formats import format_objects
from bomc_bt.site.query import open_site


def map_png(grid: OccupancyGrid) -> bytes:
    """The grid as an 8-bit grayscale PNG, top row = the largest y."""
    pixels = np.full(grid.data.shape, PGM_UNKNOWN, dtype=np.uint8)
    pixels[grid.data == FREE] = PGM_FREE
    pixels[grid.data >= 65] = PGM_OCCUPIED
    ok, png = cv2.imencode(".png", np.flipud(pixels))
    if not ok:
        raise BomcError("could not encode the map as PNG")
    return png.tobytes()


def world_file(grid: OccupancyGrid) -> str:
    """The ESRI world file (.pgw) of :func:`map_png`'s image, in map-frame metres."""
    r = grid.resolution
    height = grid.data.shape[0]
    x0 = grid.origin[0] + 0.5 * r
    y0 = grid.origin[1] + (height - 0.5) * r
    return "\n".join(f"{v:.10g}" for v in (r, 0.0, 0.0, -r, x0, y0)) + "\n"


def export_site(root: str | Path, out: str | Path, session: int | None = None,
                association: AssociationParams | None = None) -> list[Path]:
    """Write the map and the objects of the site in ``root`` into ``out``; the files written."""
    out = Path(out)
    with open_site(root, association) as site:
        grid = load_map(site.site.map_yaml)
        objects = site.objects(session=session)
    header = {"site": Path(root).resolve().name, "session": session}
    files = {
        "map.png": map_png(grid),
        "map.pgw": world_file(grid).encode(),
        "objects.geojson": format_objects(objects, "geojson", header).encode(),
        "objects.csv": format_objects(objects, "csv").encode(),
        "objects.json": format_objects(objects, "json", header).encode(),
    }
    try:
        out.mkdir(parents=True, exist_ok=True)
        for name, payload in files.items():
            atomic_write(out / name, payload)
    except OSError as exc:
        raise BomcError(f"cannot write the export ({exc.strerror})", out, "--out") from None
    return [out / name for name in files]
