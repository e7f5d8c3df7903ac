"""py_trees leaves of bomc-bt, one module per composed behaviour.

Leaves are thin: they read the robot port and the mission context, call the library in
``bomc_bt`` and turn its answers into tick statuses and feedback messages. Importing this
package registers every leaf by name in the default registry the YAML loader uses.
"""

from behaviours import (  # noqa: F401
    common,
    explore,
    look_around,
    navigate,
    perceive,
    plan_pass,
    recover,
    relocalize,
    save_map,
    session,
    waypoints,
)
from bomc_bt.tree.registry import REGISTRY


def registry():
    """The registry with every leaf of this package."""
    return REGISTRY
