"""The ``central:`` section of the configuration: the floor lease of a pass on a synchronised site."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class CentralParams:
    """How a monitor pass on a site tied to the central store holds its floor's lease."""

    lease_ttl: float = 300.0  # [s] wall time a lease lasts unless renewed: how long a crashed robot blocks the floor
    lease_renew: float = 60.0  # [s] wall time between renewals while the pass runs
    connect_timeout: float = 10.0  # [s] wall time to reach the database before giving up

    def __post_init__(self) -> None:
        if not 10.0 <= self.lease_ttl <= 86400.0:
            raise ValueError("lease_ttl must be between 10 and 86400 s")
        if not 1.0 <= self.lease_renew < self.lease_ttl:
            raise ValueError("lease_renew must be at least 1 s and shorter than lease_ttl")
        if not 1.0 <= self.connect_timeout <= 600.0:
            raise ValueError("connect_timeout must be between 1 and 600 s")
