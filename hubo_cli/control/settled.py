"""The garbage collector kept off the objects a run settles before it goes (``gc.freeze``).

A control period must not stall: a full collection scans every object the process holds, and
with the libraries, the model and the plan loaded (over 100,000 objects) one scan took 38-43 ms
in the middle of a walk, eight 5 ms periods without a command (the 0.3 m walk stopped at 2.2 s:
the worst period 39.5 ms at 2.335 s, the first walk of a process; 1.96 ms with the settled
objects frozen; docs/history/walking.md, round 23). Reading a log back and drawing plots make
many small objects too, each full scan they set off going through the settled ones again (about
0.1 s each).
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator


@contextlib.contextmanager
def settled_objects() -> Iterator[None]:
    """Keep the objects that exist now out of the garbage collector's full scans until the
    block ends. Nothing is kept longer: objects still go when their last reference does, and
    the frozen ones return to the collector afterwards. Nested blocks freeze once."""
    if gc.get_freeze_count():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
