"""The configuration: every module's parameter record, filled from YAML and validated.

Files are layered: ``config/defaults.yaml`` (shipped), then an optional robot file
(``config/sim.yaml`` or ``config/fetch.yaml``), then the user's ``--config`` file. Each
file is validated on its own before merging, so an error names the file that has it:
``my.yaml: exploration.local_radus: unknown key (expected one of: ...)``.
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any, Literal

import yaml

from bomc_bt.errors import BomcError
from bomc_bt.exploration.dwfe import ExplorationParams
from bomc_bt.graph import AssociationParams
from bomc_bt.localization import RelocalizationParams
from bomc_bt.params import from_mapping, merge
from bomc_bt.perception.projection import ProjectionParams
from bomc_bt.ros.params import RosParams
from bomc_bt.sim.camera import CameraParams
from bomc_bt.sim.detector import SimDetectorParams
from bomc_bt.sim.robot import SimParams
from bomc_bt.traversal import TraversalParams


@dataclass
class PerceptionParams:
    """Which detector and segmenter run, and what they look for."""

    backend: Literal["sim", "onnx"] = "sim"
    # Prompts (open vocabulary). Empty in the simulator: every category the world has.
    categories: list[str] = field(default_factory=list)
    onnx: dict[str, Any] = field(default_factory=dict)  # validated by the ONNX backend


@dataclass
class MissionParams:
    """Mission-wide knobs that are not a single behaviour's parameters."""

    trajectory_period: float = 1.0  # s between recorded exploration poses (the paper: 1 Hz)
    explored_area_period: float = 5.0  # s between explored-area updates of the progress line


@dataclass
class Config:
    mission: MissionParams = field(default_factory=MissionParams)
    sim: SimParams = field(default_factory=SimParams)
    exploration: ExplorationParams = field(default_factory=ExplorationParams)
    relocalization: RelocalizationParams = field(default_factory=RelocalizationParams)
    traversal: TraversalParams = field(default_factory=TraversalParams)
    camera: CameraParams = field(default_factory=CameraParams)
    detector: SimDetectorParams = field(default_factory=SimDetectorParams)
    projection: ProjectionParams = field(default_factory=ProjectionParams)
    association: AssociationParams = field(default_factory=AssociationParams)
    perception: PerceptionParams = field(default_factory=PerceptionParams)
    ros: RosParams = field(default_factory=RosParams)
    source: list[str] = field(default_factory=list)  # the files merged, in order


def resource_dir(name: str) -> Path:
    """``trees/`` or ``config/`` from a checkout, else from the installed package data."""
    checkout = Path(__file__).resolve().parent.parent / name
    if checkout.is_dir():
        return checkout
    installed = Path(sys.prefix) / "share" / "bomc-bt" / name
    if installed.is_dir():
        return installed
    raise BomcError(f"cannot find the {name}/ folder (looked in {checkout} and {installed})")


def read_yaml(path: Path) -> Any:
    """Parse a YAML file; syntax errors become one line with the position."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise BomcError("file not found", path) from None
    except OSError as exc:
        raise BomcError(f"cannot read ({exc.strerror})", path) from None
    try:
        return yaml.safe_load(text)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else "syntax"
        raise BomcError(f"invalid YAML ({exc.problem})", path, where) from None
    except yaml.YAMLError as exc:
        raise BomcError(f"invalid YAML ({exc})", path) from None


def load_config(extra: list[str | Path] = (), robot: str | None = "sim") -> Config:
    """Defaults, then ``config/<robot>.yaml`` if present, then each ``extra`` file."""
    config_dir = resource_dir("config")
    paths = [config_dir / "defaults.yaml"]
    if robot and (config_dir / f"{robot}.yaml").exists():
        paths.append(config_dir / f"{robot}.yaml")
    paths.extend(Path(p) for p in extra)
    merged: dict = {}
    for path in paths:
        data = read_yaml(path) or {}
        if not isinstance(data, dict):
            raise BomcError("expected a mapping of config sections", path)
        from_mapping(Config, data, path)  # validate this file alone: errors name it
        merged = merge(merged, data)
    config = from_mapping(Config, merged, paths[-1])
    config.source = [str(p) for p in paths]
    return config


def config_to_dict(config: Config) -> dict:
    """The effective configuration as plain YAML-able data (``bomc config``)."""
    out = asdict(config)
    out.pop("source", None)
    return _plain(out)


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if is_dataclass(value):
        return {f.name: _plain(getattr(value, f.name)) for f in fields(value)}
    return value
