"""A site: its directory layout, and the small API to ask it questions, export and correct it.

* :mod:`~bomc_bt.site.layout` -- where each file of a site lives (:class:`Site`), map
  generations, JSON and trajectory files;
* :mod:`~bomc_bt.site.query` -- read-only queries (:func:`open_site`: objects, changes);
* :mod:`~bomc_bt.site.formats` -- those results as a table, JSON, CSV, GeoJSON;
* :mod:`~bomc_bt.site.export` -- the map as PNG + world file and the objects as files;
* :mod:`~bomc_bt.site.edits` -- the operator's corrections (``bomc edit``).

Example (README "Asking a site")::

    from bomc_bt.site import open_site

    with open_site("sites/demo") as site:
        chairs = site.objects(category="chair", near=(4.0, 2.0), radius=3.0)
        for session in site.changes(since=1):
            print(session.session, [(c.kind, c.node_id) for c in session.changes])
"""

from bomc_bt.site.edits import EditResult, edit_site
from bomc_bt.site.export import export_site
from bomc_bt.site.layout import (
    GENERATIONS,
    POINTER,
    Site,
    TrajectoryRecorder,
    current_generation,
    generation_dir,
    read_json,
    write_json,
)
from bomc_bt.site.query import NodeChange, OperatorEdit, SessionChanges, SiteObject, SiteReader, open_site

__all__ = [
    "GENERATIONS", "POINTER", "EditResult", "NodeChange", "OperatorEdit", "SessionChanges", "Site", "SiteObject",
    "SiteReader", "TrajectoryRecorder", "current_generation", "edit_site", "export_site", "generation_dir",
    "open_site", "read_json", "write_json",
]
