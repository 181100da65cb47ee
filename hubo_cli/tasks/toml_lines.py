"""Where a field sits in a TOML file: line numbers for error messages.

``tomllib`` gives values but no positions, so errors are located by scanning the text for the
table header (``[stance]``, ``[scene.wall]``, the n-th ``[[steps]]``) and then the key inside
that table. Field paths look like ``stance.wall_distance_mm`` or ``steps[2].speed_mm_s`` (array
tables are numbered from 1: ``steps[2]`` is the second ``[[steps]]``).
"""

from __future__ import annotations

import re

_HEADER = re.compile(r"^\s*(\[\[?)\s*([A-Za-z0-9_.\-\" ]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-]+)\s*=")


def _parts(field: str) -> list[tuple[str, int | None]]:
    """``steps[2].speed_mm_s`` -> [("steps", 2), ("speed_mm_s", None)]."""
    out = []
    for part in field.split("."):
        match = re.fullmatch(r"([A-Za-z0-9_\-]+)(?:\[(\d+)\])?", part)
        if match is None:
            return []
        out.append((match.group(1), None if match.group(2) is None else int(match.group(2))))
    return out


def field_line(text: str, field: str) -> int | None:
    """The 1-based line of ``field`` in the TOML ``text`` (its table header when the key itself
    is absent), or None when the table is not there either."""
    parts = _parts(field)
    if not parts:
        return None
    lines = text.splitlines()
    # the deepest table written as a header: steps[2] -> the third [[steps]]; scene.wall
    table_parts = parts[:-1]
    key = parts[-1][0]
    while True:
        header = ".".join(name for name, _ in table_parts)
        index = table_parts[-1][1] if table_parts else None
        start = _find_header(lines, header, index) if table_parts else 0
        if start is not None:
            break
        # the table may be the key itself (a whole table is missing or wrong): try one up
        key = table_parts[-1][0]
        table_parts = table_parts[:-1]
    end = len(lines)
    for n in range(start + (1 if table_parts else 0), len(lines)):
        if _HEADER.match(lines[n]):
            end = n
            break
    for n in range(start + (1 if table_parts else 0), end):
        match = _KEY.match(lines[n])
        if match and match.group(1) == key:
            return n + 1
    if not table_parts:
        header = _find_header(lines, key, None)
        return None if header is None else header + 1
    return start + 1


def _find_header(lines: list[str], name: str, index: int | None) -> int | None:
    seen = -1
    for n, line in enumerate(lines):
        match = _HEADER.match(line)
        if match and match.group(2).replace('"', "").replace(" ", "") == name:
            seen += 1
            if index is None or seen == index - 1:
                return n
    return None
