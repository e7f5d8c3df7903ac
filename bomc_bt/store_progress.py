"""How the site store writes its ``progress`` rows (:mod:`bomc_bt.store`).

A value is stored as its JSON; a value a pass encoded itself (:class:`EncodedJSON`: its
resume point's rows, :mod:`bomc_bt.resume_rows`) as its text, unchanged; and
:data:`~bomc_bt.json_text.DROP` deletes the row (a part of the resume point that is no
longer in it), so one transaction can both write and remove a moment's rows.
"""

from __future__ import annotations

import json
import sqlite3
from typing import Any

from bomc_bt.json_text import DROP, EncodedJSON, to_jsonable


def put_progress(db: sqlite3.Connection, progress: dict[str, Any] | None) -> None:
    """Write (or delete) ``progress``'s rows inside the caller's transaction on ``db``."""
    for key, value in (progress or {}).items():
        if value is DROP:
            db.execute("DELETE FROM progress WHERE key=?", (key,))
        else:
            text = value.text if isinstance(value, EncodedJSON) else json.dumps(value, default=to_jsonable)
            db.execute("INSERT OR REPLACE INTO progress VALUES (?, ?)", (key, text))
