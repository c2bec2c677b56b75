"""The header every inshade JSON description opens with: an object naming its ``format`` and the
``version`` this inshade reads, holding only the fields that format knows."""
from __future__ import annotations


def check_header(data, fmt: str, known, error: type[Exception]) -> None:
    """Raise ``error`` with a field-naming message where ``data`` is not a version-1 ``fmt``
    object whose fields all lie in ``known``."""
    if not isinstance(data, dict):
        raise error("must be a JSON object")
    if data.get("format") != fmt:
        raise error(f"format: expected \"{fmt}\", got {data.get('format')!r}")
    if data.get("version") != 1:
        raise error(f"version: this inshade reads version 1, got {data.get('version')!r}")
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise error(f"{unknown[0]}: unknown field (known: {', '.join(sorted(known))})")
