"""The shipped trees: they load with every leaf's ports listed, nest at most 6 levels, and
a pass that goes well ends without a red (failed) node."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from bomc_bt.config import load_config
from bomc_bt.mission import MissionContext
from bomc_bt.site import Site
from bomc_bt.tree.decorators import DECORATORS
from bomc_bt.tree.loader import load_tree
from bomc_bt.tree.registry import load_registry
from bomc_bt.tree.view import tree_ports

TREES = Path(__file__).resolve().parent.parent / "trees"
MAX_LEVELS = 6
CHILD_KEYS = ("children", "child")


def levels(spec) -> int:
    """Levels of nodes in one definition of a tree file (a ``subtree:`` reference is one node)."""
    if not isinstance(spec, dict):
        return 0
    below = []
    for key in CHILD_KEYS:
        value = spec.get(key)
        below += value if isinstance(value, list) else [value] if value is not None else []
    return 1 + max((levels(child) for child in below), default=0)


def definition_levels(path: Path) -> dict[str, int]:
    data = yaml.safe_load(path.read_text())
    out = {f"subtrees.{name}": levels(spec) for name, spec in (data.get("subtrees") or {}).items()}
    if "root" in data:
        out["root"] = levels(data["root"])
    return out


@pytest.mark.parametrize("path", sorted(TREES.glob("*.yaml")), ids=lambda p: p.name)
def test_no_shipped_tree_nests_deeper_than_six_levels(path):
    deep = {name: n for name, n in definition_levels(path).items() if n > MAX_LEVELS}
    assert not deep, f"{path.name}: {deep} (split the deep part into its own subtree)"


def test_levels_count_nodes_not_yaml_keys():
    spec = {"sequence": "S", "children": [{"behaviour": "A"}, {"retry": {}, "child": {"subtree": "x"}}]}
    assert levels(spec) == 3
    assert "retry" in DECORATORS


def shipped_context(tmp_path) -> MissionContext:
    return MissionContext(robot=None, config=load_config(), site=Site(tmp_path), mission="monitor")


@pytest.mark.parametrize("name", ["build", "monitor"])
def test_the_mission_trees_load_with_every_leaf_listing_its_ports(name, tmp_path):
    root = load_tree(TREES / f"{name}.yaml", load_registry(), shipped_context(tmp_path), clock=lambda: 0.0,
                     require_ports=True)
    assert root.name == name.capitalize()


def preorder(node) -> list[str]:
    return [node.name] + [name for child in node.children for name in preorder(child)]


def test_the_monitor_tree_reads_like_the_papers_figure(tmp_path):
    root = load_tree(TREES / "monitor.yaml", load_registry(), shipped_context(tmp_path), clock=lambda: 0.0)
    names = preorder(root)
    order = ["Start Session", "Relocalize", "Traverse And Perceive", "Traverse Waypoints", "Plan Traversal",
             "Visit Waypoints", "Cover Gaps", "Refresh Stale", "Perceive Associate", "Pair Relocations",
             "End Session"]
    positions = [names.index(n) for n in order]
    assert positions == sorted(positions)
    ports = tree_ports(root)
    assert set(ports["/goal"]["writes"]) == {"Next Waypoint", "Find Detour", "Way Back"}  # Way Back: a back-out
    assert set(ports["/nav_detour"]["reads"]) == {"Mark Visited", "Mark Detoured", "Mark Missed"}
    assert ports["/localized"]["writes"][:2] == ["Relocalize Local", "Relocalize Global"]
    assert set(ports["/localized"]["writes"][2:]) == {"Relocalize Where It Is", "Relocalize Globally"}
    # after each waypoint the loop checks that the pass still gets somewhere (trees/recover.yaml)
    recovery = ["Reach Waypoint", "Keep Going", "Making Progress", "Find Out Why", "Act On It", "End Pass Early"]
    positions = [names.index(n) for n in recovery]
    assert positions == sorted(positions)
    assert set(ports["/stuck_cause"]["writes"]) == {"Find Out Why"}  # one per visit loop


def test_a_tree_param_that_is_a_config_value_is_refused(tmp_path):
    tree = tmp_path / "t.yaml"
    tree.write_text("version: 1\nroot: {behaviour: LookAround, params: {radius: 3.0}}\n")
    with pytest.raises(Exception, match="radius is the configuration's projection.expect_range"):
        load_tree(tree, load_registry(), shipped_context(tmp_path), clock=lambda: 0.0)


def test_leaves_read_config_values_and_the_one_staleness_limit(tmp_path):
    ctx = shipped_context(tmp_path)
    ctx.config.mission.stale_after = 450.0  # an operator's config file: both leaves follow it
    root = load_tree(TREES / "monitor.yaml", load_registry(), ctx, clock=lambda: 0.0)
    leaves = {node.name: node for node in root.iterate()}
    expect = ctx.config.projection.expect_range
    assert leaves["Look Around"].params.radius == expect
    assert leaves["Plan Gap Viewpoints"].params.view_range == expect
    assert leaves["Plan Refresh Stops"].params.view_range == expect
    assert leaves["Look Around"].params.refresh_after == leaves["Plan Refresh Stops"].params.stale_after == 450.0
