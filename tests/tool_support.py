"""The repository's tools (``tools/NAME.py``, scripts rather than a package) loaded as modules
for their tests."""

from __future__ import annotations

import functools
import importlib.util
import sys
from pathlib import Path

TOOLS = Path(__file__).resolve().parent.parent / "tools"


@functools.cache
def load_tool(name: str):
    """``tools/NAME.py`` as a module, loaded once; the tools folder is on ``sys.path`` while it
    loads (a tool imports its siblings: side_push_bound, walk_disturbances)."""
    sys.path.insert(0, str(TOOLS))
    try:
        spec = importlib.util.spec_from_file_location(name, TOOLS / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(TOOLS))
    return module
