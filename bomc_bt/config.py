"""The configuration: every module's parameter record, filled from YAML and validated.

Files are layered: ``config/defaults.yaml`` (shipped), then an optional robot file
(``config/sim.yaml`` or ``config/fetch.yaml``), then the user's ``--config`` file. Each
file is validated on its own before merging, so an error names the file that has it:
``my.yaml: exploration.local_radus: unknown key (expected one of: ...)``.
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

from bomc_bt.algorithm_params import (
    BudgetParams,
    ExplorationParams,
    ProjectionParams,
    RecoveryParams,
    TraversalParams,
)
from bomc_bt.central.params import CentralParams
from bomc_bt.config_docs import documented_yaml, plain
from bomc_bt.errors import BomcError
from bomc_bt.graph import AssociationParams
from bomc_bt.params import from_mapping, merge
from bomc_bt.relocalization_params import RelocalizationParams
from bomc_bt.ros.params import RosParams
from bomc_bt.sim.params import CameraParams, SimDetectorParams, SimParams
from bomc_bt.yaml_io import read_yaml


@dataclass
class PerceptionParams:
    """Which detector and segmenter run, and what they look for."""

    backend: Literal["sim", "onnx"] = "sim"  # [choice] "sim": the simulator's detector; "onnx": the ONNX models
    # [list] prompts (open vocabulary); empty in the simulator: every category the world has
    categories: list[str] = field(default_factory=list)
    onnx: dict[str, Any] = field(default_factory=dict)  # [text] the ONNX backend's settings (it validates them)


@dataclass
class MissionParams:
    """Mission-wide knobs that are not a single behaviour's parameters."""

    trajectory_period: float = 1.0  # [s] between recorded exploration poses (the paper: 1 Hz)
    explored_area_period: float = 5.0  # [s] between explored-area updates of the progress line
    # [s] robot time since this pass last confirmed a node after which it is stale: worth
    # another look (Look Around) and a refresh stop (Refresh Stale); 0: never stale
    stale_after: float = 600.0
    timeline: bool = True  # [bool] record the pass's timeline (sessions/<n>/timeline.jsonl) for replay in bomc view
    timeline_pose_period: float = 0.5  # [s] robot time between the timeline's poses and feedback messages
    timeline_flush_period: float = 1.0  # [s] wall time between writes of the timeline to disk (a kill loses less)

    def __post_init__(self) -> None:
        if self.stale_after < 0:
            raise ValueError("stale_after must be >= 0 (0: never stale)")
        if not 0 < self.timeline_pose_period <= 3600:
            raise ValueError("timeline_pose_period must be more than 0 and at most 3600 s")
        if not 0 <= self.timeline_flush_period <= 3600:
            raise ValueError("timeline_flush_period must be 0 to 3600 s")


@dataclass
class Config:
    """Every module's parameters: one section per record."""

    mission: MissionParams = field(default_factory=MissionParams)
    sim: SimParams = field(default_factory=SimParams)
    exploration: ExplorationParams = field(default_factory=ExplorationParams)
    relocalization: RelocalizationParams = field(default_factory=RelocalizationParams)
    traversal: TraversalParams = field(default_factory=TraversalParams)
    budget: BudgetParams = field(default_factory=BudgetParams)
    recovery: RecoveryParams = field(default_factory=RecoveryParams)
    camera: CameraParams = field(default_factory=CameraParams)
    detector: SimDetectorParams = field(default_factory=SimDetectorParams)
    projection: ProjectionParams = field(default_factory=ProjectionParams)
    association: AssociationParams = field(default_factory=AssociationParams)
    perception: PerceptionParams = field(default_factory=PerceptionParams)
    ros: RosParams = field(default_factory=RosParams)
    central: CentralParams = field(default_factory=CentralParams)
    source: list[str] = field(default_factory=list, init=False)  # the files merged, in order


REMOVED_KEYS = {
    ("sim", "scene", "lidar_height"): "the scan plane's height is sim.lidar.height (one value for laser and scene)",
}
"""Keys that older files may still set, with what replaced them: an error, not a silent no-op."""


def resource_dir(name: str) -> Path:
    """``trees/`` or ``config/`` from a checkout, else from the installed package data."""
    checkout = Path(__file__).resolve().parent.parent / name
    if checkout.is_dir():
        return checkout
    installed = Path(sys.prefix) / "share" / "bomc-bt" / name
    if installed.is_dir():
        return installed
    raise BomcError(f"cannot find the {name}/ folder (looked in {checkout} and {installed})")


def load_config(extra: list[str | Path] = (), robot: str | None = "sim") -> Config:
    """Defaults, then ``config/<robot>.yaml`` if present, then each ``extra`` file."""
    config_dir = resource_dir("config")
    paths = [config_dir / "defaults.yaml"]
    if robot and (config_dir / f"{robot}.yaml").exists():
        paths.append(config_dir / f"{robot}.yaml")
    paths.extend(Path(p) for p in extra)
    merged: dict = {}
    for path in paths:
        data = read_yaml(path, "config file") or {}
        if not isinstance(data, dict):
            raise BomcError("expected a mapping of config sections", path)
        _refuse_removed_keys(data, path)
        from_mapping(Config, data, path)  # validate this file alone: errors name it
        merged = merge(merged, data)
    config = from_mapping(Config, merged, paths[-1])
    config.source = [str(p) for p in paths]
    return config


def _refuse_removed_keys(data: dict, path: Path) -> None:
    for keys, replacement in REMOVED_KEYS.items():
        section = data
        for key in keys[:-1]:
            section = section.get(key) if isinstance(section, dict) else None
        if isinstance(section, dict) and keys[-1] in section:
            raise BomcError(f"removed: {replacement}", path, ".".join(keys))


DEFAULTS_HEADER = """\
# bomc-bt parameters: every module's defaults, validated on load (bomc_bt/config.py).
# Layer your own file over this one with --config FILE; `bomc config` prints the result.
# Generated by `bomc config --defaults > config/defaults.yaml`; tests/test_config.py
# checks that it matches the code.
"""

EFFECTIVE_HEADER = """\
# bomc-bt parameters in effect: {files} (later files win).
"""


def defaults_yaml() -> str:
    """``config/defaults.yaml`` as the code defines it, every field with its unit and meaning."""
    return DEFAULTS_HEADER + documented_yaml(Config())


def config_to_dict(config: Any) -> dict:
    """The effective configuration (or any record) as plain YAML-able data."""
    out = asdict(config)
    out.pop("source", None)
    return plain(out)
