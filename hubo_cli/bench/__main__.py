"""Run every benchmark module and print a table of figures."""

from __future__ import annotations

import importlib
import pkgutil
import sys
import time

import hubo_cli.bench as bench_pkg

ON_REQUEST = {"robustness", "walk_sweep"}  # slow (minutes): only when named, e.g. BENCH=robustness


def main(argv: list[str]) -> int:
    only = set(argv)
    rows: list[tuple[str, str, str, str]] = []

    def report(name: str, value: float, unit: str, note: str = "") -> None:
        text = f"{value:,.3g}" if abs(value) < 1000 else f"{value:,.0f}"
        rows.append((name, text, unit, note))
        print(f"  {name:<58} {text:>12} {unit:<14} {note}", flush=True)

    failed: list[str] = []
    modules = sorted(m.name for m in pkgutil.iter_modules(bench_pkg.__path__)
                     if not m.name.startswith("_"))
    unknown = sorted(only - set(modules))
    if unknown:  # review 22: `make bench BENCH=walkng` ran nothing and exited 0
        print(f"bench: no module {', '.join(unknown)}; the modules: {', '.join(modules)}",
              file=sys.stderr)
        return 2
    for name in modules:
        if (only and name not in only) or (not only and name in ON_REQUEST):
            continue
        print(f"[{name}]", flush=True)
        t0 = time.perf_counter()
        try:
            importlib.import_module(f"hubo_cli.bench.{name}").run(report)
        except Exception as error:  # one module's failure must not hide the others' figures
            failed.append(name)
            print(f"  failed: {type(error).__name__}: {error}", flush=True)
        print(f"  ({time.perf_counter() - t0:.1f} s)", flush=True)
    if failed:
        print(f"bench: {len(failed)} module(s) failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
