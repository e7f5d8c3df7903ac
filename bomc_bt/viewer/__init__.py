"""The web viewer: a local page that shows a running mission live, or a finished site.

``serve_live(port)`` gives a started server and a factory ``ctx -> on_tick hook`` for
``run_build`` / ``run_monitor``; ``serve_site(site_dir, port)`` serves a finished site
(the graph after each session and the difference between two). Standard library only.
"""

from bomc_bt.viewer.live import ViewerHook
from bomc_bt.viewer.sections import change_json
from bomc_bt.viewer.server import DEFAULT_PORT, Server, serve_live, serve_site
from bomc_bt.viewer.site import SiteView
from bomc_bt.viewer.store import StateStore, ViewerParams

__all__ = [
    "DEFAULT_PORT", "Server", "SiteView", "StateStore", "ViewerHook", "ViewerParams", "change_json",
    "serve_live", "serve_site",
]
