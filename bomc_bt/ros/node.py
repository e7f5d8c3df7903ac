"""This process's ROS node, and a bounded check that the ROS master answers.

rospy allows one node per process and ``rospy.init_node`` retries an unreachable master
for ever, so both the executive and the sim bridge ask the master first, with a socket
timeout: no roscore is a one-line error within seconds, not a hang.
"""

from __future__ import annotations

from typing import Any

from bomc_bt.errors import BomcError
from bomc_bt.ros import import_ros

NODE_NAME = "bomc_executive"
MASTER_TIMEOUT = 3.0  # wall s to wait for the ROS master to answer before init_node


def ensure_node(name: str = NODE_NAME) -> Any:
    """Initialise this process's ROS node once and return ``rospy``."""
    rospy = import_ros()
    if not rospy.core.is_initialized():
        check_master()
        try:
            rospy.init_node(name, anonymous=False, disable_signals=True)
        except Exception as exc:  # master unreachable: rospy raises several kinds
            raise _no_master(exc) from None
    return rospy


def check_master(timeout: float = MASTER_TIMEOUT) -> None:
    """Ask the master for its pid, bounded by ``timeout``; a BomcError if it does not answer."""
    import xmlrpc.client

    import rosgraph

    class Transport(xmlrpc.client.Transport):  # xmlrpc's default connection never times out
        def make_connection(self, host: Any) -> Any:
            conn = super().make_connection(host)
            conn.timeout = timeout
            return conn

    try:
        proxy = xmlrpc.client.ServerProxy(rosgraph.get_master_uri(), transport=Transport())
        proxy.getPid(f"/{NODE_NAME}_probe")
    except Exception as exc:  # refused, timed out, unresolvable host, a bad URI
        raise _no_master(exc) from None


def _no_master(exc: Exception) -> BomcError:
    import rosgraph

    return BomcError(
        f"cannot reach the ROS master at {rosgraph.get_master_uri()} ({exc}); "
        "is roscore running and ROS_MASTER_URI set?",
        None,
        "ROS_MASTER_URI",
    )
