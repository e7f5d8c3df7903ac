"""ROS 1 backend: the robot port over rospy, RViz publishing and the sim-over-ROS bridge.

ROS 1 comes from Debian's packages, which install into the system interpreter's
``/usr/lib/python3/dist-packages``. The executive runs in its own venv, so
:func:`import_ros` *appends* that folder to ``sys.path`` (never prepends: Debian's numpy
and yaml must not shadow the venv's) and imports rospy, or says how to install it.
Nothing in this package imports rospy at module level, so ``bomc`` without ``--ros``
never needs ROS.
"""

from __future__ import annotations

import sys
from types import ModuleType

from bomc_bt.errors import BomcError

ROS_PYTHON_PATH = "/usr/lib/python3/dist-packages"
APT_PACKAGES = (
    "ros-core python3-rospy python3-actionlib python3-move-base-msgs python3-nav-msgs "
    "python3-sensor-msgs python3-geometry-msgs python3-tf2-ros python3-visualization-msgs "
    "python3-std-srvs"
)
INSTALL_HINT = f"install ROS 1 from Debian: sudo apt-get install -y {APT_PACKAGES}"


def import_ros() -> ModuleType:
    """Import and return ``rospy``; a :class:`BomcError` with the apt command if it is missing."""
    if ROS_PYTHON_PATH not in sys.path:
        sys.path.append(ROS_PYTHON_PATH)
    try:
        import actionlib  # noqa: F401
        import rospy
        import tf2_ros  # noqa: F401
        from move_base_msgs.msg import MoveBaseAction  # noqa: F401
        from nav_msgs.msg import OccupancyGrid  # noqa: F401
        from sensor_msgs.msg import Image  # noqa: F401
        from std_srvs.srv import Empty  # noqa: F401
        from visualization_msgs.msg import MarkerArray  # noqa: F401
    except ImportError as exc:
        raise BomcError(f"ROS 1 is not available ({exc}); {INSTALL_HINT}", None, "--ros") from None
    return rospy
