"""What a written asset, bundle or report records of when it was made: one clock, one format (UTC to
the second, ISO 8601), so records compare and sort alike whoever wrote them."""
from __future__ import annotations

import datetime


def utc_now() -> str:
    """The time now, UTC, to the second: ``2026-12-06T22:33:54+00:00``."""
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def recorded_at() -> dict:
    """``{"date_utc": ...}``: when a provenance or metrics record was made, spread into it where it is
    written, so every record names its time with the one key and format."""
    return {"date_utc": utc_now()}
