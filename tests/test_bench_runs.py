"""The benchmarks themselves run: `make bench` is how issues' figures are measured, and a
benchmark that wraps a private method breaks silently when that method's signature changes
(round 21: the standing bench's clock broke with the loop's pacing call in round 15 and
ended `make bench` at its [standing] section, hiding every later module's figures)."""

from __future__ import annotations

import math
import re

from hubo_cli.bench import __main__ as bench_main
from hubo_cli.bench import standing
from hubo_cli.control.loop import ControlLoop
from hubo_cli.model import load_model


def test_the_standing_bench_times_a_real_standing_run(monkeypatch):
    monkeypatch.setattr(standing, "SECONDS", 0.5)
    monkeypatch.setattr(standing, "WARMUP", 5)
    pace = ControlLoop._pace
    figures = standing._standing_run(load_model())
    assert ControlLoop._pace is pace  # the clock's wrapper is taken off again
    assert set(figures) == {"wall_s", "cpu_s", "step_cpu_s", "step_wall_s", "cpu_ratio",
                            "wall_ratio"}
    assert all(math.isfinite(v) and v > 0 for v in figures.values()), figures


def test_a_failing_bench_module_is_reported_and_the_others_still_run(monkeypatch, capsys):
    ran = []

    class Broken:
        @staticmethod
        def run(report):
            raise TypeError("a wrapped signature changed")

    class Fine:
        @staticmethod
        def run(report):
            ran.append("fine")
            report("a figure", 1.0, "us")

    modules = {"hubo_cli.bench.aaa": Broken, "hubo_cli.bench.zzz": Fine}
    monkeypatch.setattr(bench_main.pkgutil, "iter_modules", lambda path: [
        type("M", (), {"name": name.rsplit(".", 1)[1]})() for name in modules])
    monkeypatch.setattr(bench_main.importlib, "import_module", modules.__getitem__)
    assert bench_main.main([]) == 1
    out, err = capsys.readouterr()
    assert ran == ["fine"]
    assert "failed: TypeError: a wrapped signature changed" in out
    # each module's footer reads the machine's yardstick around it (round 26)
    assert len(re.findall(r"the reference loop \d+\.\d ms before, \d+\.\d ms after", out)) == 2
    assert "1 module(s) failed: aaa" in err


def test_an_unknown_bench_module_is_refused_not_a_silent_pass(capsys):
    """Review 22: `make bench BENCH=walkng` (or `--help`) ran no module and exited 0."""
    assert bench_main.main(["walkng"]) == 2
    assert bench_main.main(["--help"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "bench: no module walkng; the modules: " in err and "walking" in err
