"""Write the HUBO 2+ URDF files from the robot model: ``python tools/make_urdf.py [--check]``.

The logic lives in :mod:`hubo_cli.urdf`; this script only writes (or, with ``--check``, compares)
``robots/hubo2plus/hubo2plus.urdf`` and ``robots/hubo2plus/hubo2plus-drill.urdf``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hubo_cli.model import load_model
from hubo_cli.urdf import urdf_variants

ROBOT_DIR = Path(__file__).resolve().parent.parent / "robots" / "hubo2plus"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="only compare the files on disk with the generator's output")
    args = parser.parse_args(argv)
    model = load_model("as-built")
    stale = []
    for name, text in urdf_variants(model).items():
        path = ROBOT_DIR / name
        if args.check:
            if not path.is_file() or path.read_text() != text:
                stale.append(name)
        else:
            path.write_text(text)
            print(f"wrote {path}")
    if stale:
        print(f"out of date: {', '.join(stale)} (run python tools/make_urdf.py)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
