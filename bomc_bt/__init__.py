"""bomc-bt: a behaviour-tree mission executive for build-once, monitor-continuously robots.

The library (this package) holds plain, typed algorithms and the robot port; the
py_trees leaves live in the top-level ``behaviours`` package and the trees in ``trees/``.
"""

__version__ = "0.1.0"
