"""Where the shared worlds and maps live, for the benchmarks (as ``tests/shared_data.py`` for the tests).

``$BOMC_SHARED`` if set, else ``shared/`` beside the checkout. Benchmarks run as scripts
(``python benchmarks/bench_x.py``), so this module sits beside them on their path.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ["BOMC_SHARED"]) if os.environ.get("BOMC_SHARED") else REPO.parent / "shared"
