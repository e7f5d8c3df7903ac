"""Does a tree file fit the mission it is given to? Checked before anything of the site is written.

``bomc monitor --tree trees/build.yaml`` used to run exploration against the saved site
and leave ``trajectory.csv`` with only its header; ``bomc build --tree trees/monitor.yaml``
ended in a traceback. A mission tree is recognised by the leaves that make the mission:
a build explores (``StartExploration`` opens the trajectory the passes plan on), a pass
opens and closes its session (``StartSession`` / ``EndSession``); the leaves that write
the other mission's files are refused.
"""

from __future__ import annotations

from pathlib import Path

from bomc_bt.errors import BomcError

REQUIRED = {"build": ("StartExploration",), "monitor": ("StartSession", "EndSession")}
REFUSED = {"build": ("StartSession", "EndSession", "PerceiveAssociate"), "monitor": ("StartExploration", "SaveMap")}


def check_mission_tree(path: Path, mission: str) -> None:
    """Raise a one-line BomcError (``--tree``) when the tree in ``path`` is not a ``mission`` tree."""
    from bomc_bt.tree.loader import load_tree
    from bomc_bt.tree.registry import load_registry

    registry = load_registry()
    names = {registry.get(name): name for name in registry.names()}
    root = load_tree(path, registry, context=None, clock=lambda: 0.0)
    used = {names.get(type(node), type(node).__name__) for node in root.iterate()}
    missing = [name for name in REQUIRED[mission] if name not in used]
    wrong = [name for name in REFUSED[mission] if name in used]
    if missing or wrong:
        why = f"has {', '.join(wrong)}" if wrong else f"lacks {', '.join(missing)}"
        raise BomcError(f"not a {mission} tree: it {why} (a {mission} tree has {', '.join(REQUIRED[mission])})",
                        path, "--tree")
