"""Run every benchmark module and print a table of figures."""

from __future__ import annotations

import importlib
import pkgutil
import sys
import time

import hubo_cli.bench as bench_pkg

ON_REQUEST = {"robustness", "walk_sweep"}  # slow (minutes): only when named, e.g. BENCH=robustness
REFERENCE_LOOP = 300_000  # iterations of the machine's yardstick (reference_ms)


def reference_ms() -> float:
    """A fixed pure-Python loop's wall time (ms), read before and after each module: the
    machine's own speed then. Round 26's machine ran it in about 11 ms or about 21 ms,
    switching between the two from one second to the next, and every figure with it; a
    figure is read against the yardstick around it (a ratio of one run), not across
    machines or hours."""
    t0 = time.perf_counter()
    total = 0.0
    for i in range(REFERENCE_LOOP):
        total += i * 0.5
    return (time.perf_counter() - t0) * 1e3


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
        before_ms = reference_ms()
        t0 = time.perf_counter()
        try:
            importlib.import_module(f"hubo_cli.bench.{name}").run(report)
        except Exception as error:  # one module's failure must not hide the others' figures
            failed.append(name)
            print(f"  failed: {type(error).__name__}: {error}", flush=True)
        elapsed_s = time.perf_counter() - t0
        print(f"  ({elapsed_s:.1f} s; the reference loop {before_ms:.1f} ms before, "
              f"{reference_ms():.1f} ms after)", flush=True)
    if failed:
        print(f"bench: {len(failed)} module(s) failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
