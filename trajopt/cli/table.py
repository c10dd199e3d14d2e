"""The two-column tables the commands print: ``  key    value``, the keys padded to one width."""
from __future__ import annotations

__all__ = ["print_table"]


def print_table(rows: list[tuple[str, str]]) -> None:
    """Print ``rows`` (``(key, value)`` pairs) to stdout, two spaces in, the values aligned."""
    if not rows:
        return
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k.ljust(w)}  {v}")
