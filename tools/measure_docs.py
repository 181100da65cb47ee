"""Measure the numbers a newcomer relies on and write them where the docs include them.

Every measured figure on the README's first screen and on the site's user pages (outside the
history) comes from here, never typed by hand:

    python tools/measure_docs.py run       # make run's command: time, the cut's figures (~70 s)
    python tools/measure_docs.py walk      # hubo walk --to 1.0 0 0: final error, steps (~30 s)
    python tools/measure_docs.py teleop    # the shipped recordings replayed in free and drill
                                           # mode on the simulated robot (~1-2 min)
    python tools/measure_docs.py push      # hubo sim --push: pushes held in place, one caught
                                           # by a step (~30 s)
    python tools/measure_docs.py bench     # make bench's parts that take seconds (~1-2 min)
    python tools/measure_docs.py install   # a fresh `make .venv/.installed-stamp` in a scratch
                                           # clone of HEAD, pip's cache warm and cold (minutes,
                                           # 2-3 GB of disk each, removed afterwards)
    python tools/measure_docs.py suite     # the whole test suite as `make test` runs it
    python tools/measure_docs.py render    # only rewrite the pages from the stored figures

Each part stores its figures in docs/generated/measured.json (with when and on what machine;
the other parts' figures stay) and rewrites docs/generated/*.md (included by the site's pages
through pymdownx.snippets) and the README's block between the ``measured`` markers.
tests/test_docs.py checks that the README's block is what the stored figures render to.
Run it from the repository with the project's environment (.venv/bin/python).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GENERATED = ROOT / "docs" / "generated"
MEASURED = GENERATED / "measured.json"
README = ROOT / "README.md"
README_BEGIN = "<!-- measured: written by tools/measure_docs.py, do not edit -->"
README_END = "<!-- /measured -->"
PARTS = ("run", "walk", "teleop", "push", "bench", "install", "suite")
# the replays the teleoperation page shows: (file, mode)
TELEOP_REPLAYS = (("drill-rectangle.csv", "free"), ("drill-rectangle.csv", "drill"),
                  ("two-hand-free.csv", "free"), ("two-hand-free.csv", "drill"))
# the pushes the walking page shows: (force N, direction, extra options); 10 s of standing
# (the push at 1 s) lets the robot come upright again after the hip strategy's bow
PUSHES = ((90, "forward", ()), (90, "backward", ()), (60, "left", ()),
          (150, "forward", ("--step",)))
PUSH_DURATION_S = 10.0
# the make bench modules whose figures the performance page shows (the cheap ones: task runs
# the default cut twice and robustness a sweep; make bench prints those)
BENCH_MODULES = ("kinematics", "fastrak", "pipeline", "walking", "balance", "sim", "workspace",
                 "teleop")


def machine() -> str:
    """The CPU model and core count, the figures' context."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores"


def stamp(load_before: float) -> dict:
    """When, on what, and how busy the machine was (1-minute load average as it began)."""
    return {"measured_utc": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
            "machine": machine(), "load": round(load_before, 1)}


def hubo_command() -> list[str]:
    """The hubo console script beside this interpreter (the one make run calls)."""
    script = Path(sys.executable).parent / "hubo"
    return [str(script)] if script.exists() else [sys.executable, "-m", "hubo_cli.cli.main"]


def timed(cmd: list[str], **kwargs) -> tuple[float, subprocess.CompletedProcess]:
    t0 = time.perf_counter()
    done = subprocess.run(cmd, check=False, **kwargs)
    elapsed = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"error: {' '.join(cmd)} exited {done.returncode}")
    return elapsed, done


def measure_run() -> dict:
    """make run's command (the default cut with its video), timed; the cut's figures."""
    busy = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="hubo-measure-") as tmp:
        out = Path(tmp) / "run"
        cmd = [*hubo_command(), "task", "cut-rectangle", "--video", "--out", str(out)]
        elapsed, _ = timed(cmd, cwd=ROOT, stdout=subprocess.DEVNULL)
        s = json.loads((out / "summary.json").read_text())
    torque = s["wrist_torque_nm"]
    return stamp(busy) | {
        "command": "hubo task cut-rectangle --video (make run)",
        "wall_clock_s": elapsed, "duration_s": s["duration_s"], "completed": s["completed"],
        "bit_rms_mm": s["rms_error_mm"], "bit_max_mm": s["max_error_mm"],
        "hole_rms_mm": s["hole_rms_error_mm"], "max_tilt_deg": s["max_torso_tilt_deg"],
        "min_support_margin_mm": s["min_support_margin_mm"],
        "wall_distance_mm": s["stance"]["wall_distance_mm"],
        "room_mm": s["stance"]["room_mm"],
        "torque_horizontal_nm": [torque["horizontal"]["mean"], torque["horizontal"]["max"]],
        "torque_vertical_nm": [torque["vertical"]["mean"], torque["vertical"]["max"]],
        "torque_limit_nm": torque["limit"],
        "estop_events": len(s["estop_events"]), "collision_holds": len(s["collision_holds"]),
        "status_counts": s["status_counts"],
    }


def measure_walk() -> dict:
    """hubo walk --to 1.0 0 0 on the nominal robot."""
    busy = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="hubo-measure-") as tmp:
        cmd = [*hubo_command(), "walk", "--to", "1.0", "0", "0", "--json",
               "--out", str(Path(tmp) / "walk")]
        elapsed, done = timed(cmd, cwd=ROOT, stdout=subprocess.PIPE, text=True)
    s = json.loads(done.stdout)
    return stamp(busy) | {"command": "hubo walk --to 1.0 0 0", "wall_clock_s": elapsed,
                      "fell": s["fell"], "final_error_mm": s["final_error_mm"],
                      "final_error_deg": s["final_error_deg"], "steps": s["steps"],
                      "average_speed_m_s": s["average_speed_m_s"],
                      "zmp_inside_percent": 100 * s["zmp_inside_fraction"]}


def measure_teleop() -> dict:
    """The shipped recordings replayed in free and drill mode on the simulated robot."""
    busy = os.getloadavg()[0]
    replays = []
    with tempfile.TemporaryDirectory(prefix="hubo-measure-") as tmp:
        for i, (name, mode) in enumerate(TELEOP_REPLAYS):
            cmd = [*hubo_command(), "teleop", "--replay", f"trajectories/{name}", "--mode", mode,
                   "--driver", "sim", "--json", "--out", str(Path(tmp) / str(i))]
            elapsed, done = timed(cmd, cwd=ROOT, stdout=subprocess.PIPE, text=True)
            s = json.loads(done.stdout)
            replays.append({
                "replay": name, "mode": mode, "ended": s["ended"], "wall_clock_s": elapsed,
                "position_rms_mm": s["rms_error_mm"], "world_rms_mm": s["world_rms_error_mm"],
                "max_excursion_mm": {a: r["max_excursion_mm"] for a, r in s["reach"].items()},
                "at_limit_s": {a: r["at_limit_s"] for a, r in s["reach"].items()},
                "branch_changes": sum(r["branch_changes"] for r in s["reach"].values()),
                "max_tilt_deg": s["max_torso_tilt_deg"],
                "estop_events": len(s["estop_events"]),
                "collision_holds": len(s["collision_holds"])})
    return stamp(busy) | {"replays": replays}


def measure_push() -> dict:
    """hubo sim --push: a few 0.2 s pushes on the torso of the standing robot."""
    busy = os.getloadavg()[0]
    pushes = []
    with tempfile.TemporaryDirectory(prefix="hubo-measure-") as tmp:
        for i, (force, direction, extra) in enumerate(PUSHES):
            cmd = [*hubo_command(), "sim", "--push", str(force), "--push-direction", direction,
                   *extra, "--duration", f"{PUSH_DURATION_S:g}", "--json",
                   "--out", str(Path(tmp) / str(i))]
            _, done = timed(cmd, cwd=ROOT, stdout=subprocess.PIPE, text=True)
            s = json.loads(done.stdout)
            step = s.get("capture_step") or {}
            pushes.append({"command": " ".join(["hubo sim --push", str(force),
                                                "--push-direction", direction, *extra]),
                           "fell": s["fell"], "max_tilt_deg": s["max_tilt_deg"],
                           "final_tilt_deg": s["final_tilt_deg"],
                           "max_foot_shift_mm": s["max_foot_shift_mm"],
                           "steps": step.get("steps", 0),
                           "stops": [f"{e['kind']} ({', '.join(e.get('sources') or [])}) at "
                                     f"{e['t_s']:.2f} s" for e in s["estop_events"]]})
    return stamp(busy) | {"duration_s": PUSH_DURATION_S, "pushes": pushes}


def measure_bench() -> dict:
    """The make bench modules the performance page shows (python -m hubo_cli.bench MODULE ...)."""
    busy = os.getloadavg()[0]
    # a part that stops keeps the figures it reported and says why it stopped
    code = ("import importlib, json, sys\n"
            "rows, failures = [], []\n"
            "for m in sys.argv[1:]:\n"
            "    try:\n"
            "        importlib.import_module('hubo_cli.bench.' + m).run(\n"
            "            lambda name, value, unit, note='', m=m: rows.append(\n"
            "                {'module': m, 'name': name.strip(), 'value': float(value),\n"
            "                 'unit': unit, 'note': note}))\n"
            "    except Exception as exc:\n"
            "        failures.append({'module': m, 'error': f'{type(exc).__name__}: {exc}'})\n"
            "print(json.dumps({'rows': rows, 'failures': failures}))\n")
    _, done = timed([sys.executable, "-c", code, *BENCH_MODULES], cwd=ROOT,
                    stdout=subprocess.PIPE, text=True)
    return stamp(busy) | {"command": f"make bench BENCH=\"{' '.join(BENCH_MODULES)}\"",
                          **json.loads(done.stdout.strip().splitlines()[-1])}


def measure_install(cold: bool) -> dict:
    """A fresh `make .venv/.installed-stamp` in a scratch clone of HEAD; the venv's size."""
    busy = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="hubo-install-") as tmp:
        clone = Path(tmp) / "clone"
        subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(ROOT), str(clone)],
                       check=True)
        env = {k: v for k, v in os.environ.items()
               if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME")}
        if cold:
            env["PIP_NO_CACHE_DIR"] = "1"
        elapsed, _ = timed(["make", ".venv/.installed-stamp"], cwd=clone, env=env,
                           stdout=subprocess.DEVNULL)
        du = subprocess.run(["du", "-sk", str(clone / ".venv")], check=True,
                            capture_output=True, text=True)
        size_gb = int(du.stdout.split()[0]) * 1024 / 1e9
    return stamp(busy) | {"wall_clock_s": elapsed, "venv_gb": size_gb,
                      "pip_cache": "cold (PIP_NO_CACHE_DIR=1)" if cold else "warm"}


def measure_suite() -> dict:
    """The whole suite: `make test` itself (the tests on every core, then the real-time ones
    one at a time), with the environment already installed."""
    busy = os.getloadavg()[0]
    elapsed, _ = timed(["make", "test"], cwd=ROOT, stdout=subprocess.DEVNULL)
    return stamp(busy) | {"wall_clock_s": elapsed, "command": "make test"}


# ---------------------------------------------------------------------------- rendering

def _when(entry: dict) -> str:
    load = f", load {entry['load']:g}" if "load" in entry else ""
    return f"measured {entry['measured_utc']} on {entry['machine']}{load}"


def _missing(part: str) -> str:
    return f"not measured yet: `python tools/measure_docs.py {part}`"


def install_cost(m: dict) -> str:
    """One line: the first install's time and size (the README's first screen)."""
    warm, cold = m.get("install_warm"), m.get("install_cold")
    if not warm:
        return f"First install: {_missing('install')}."
    line = (f"First install (`make` does it): {warm['wall_clock_s']:.0f} s with pip's cache warm"
            + (f", {cold['wall_clock_s']:.0f} s cold" if cold else "")
            + f"; `.venv` takes {warm['venv_gb']:.1f} GB of disk.")
    return line


def readme_block(m: dict) -> str:
    run, suite = m.get("run"), m.get("suite")
    lines = [install_cost(m)]
    lines.append(f"`make run` takes {run['wall_clock_s']:.0f} s (the {run['duration_s']:.0f} s "
                 f"simulated cut and its video); " if run else f"`make run`: {_missing('run')}; ")
    where = m.get("run") or m.get("install_warm")
    elsewhere = (f" (on {suite['machine']})" if suite and where
                 and suite.get("machine") != where.get("machine") else "")
    lines[-1] += (f"`make test` {suite['wall_clock_s'] / 60:.1f} min{elsewhere}." if suite
                  else f"`make test`: {_missing('suite')}.")
    if where:
        lines.append(f"(Measured by tools/measure_docs.py on {where['machine']}: "
                     f"[how and when](docs/measured.md).)")
    return "\n".join(lines)


def page_install(m: dict) -> str:
    rows = ["| | time | `.venv` size | |", "|---|---|---|---|"]
    for key, label in (("install_warm", "pip's cache warm"),
                       ("install_cold", "pip's cache cold (`PIP_NO_CACHE_DIR=1`)")):
        e = m.get(key)
        rows.append(f"| {label} | {e['wall_clock_s']:.0f} s | {e['venv_gb']:.1f} GB | "
                    f"{_when(e)} |" if e else f"| {label} | {_missing('install')} | | |")
    return "\n".join(rows) + "\n"


def page_default_cut(m: dict) -> str:
    r = m.get("run")
    if not r:
        return f"The default cut: {_missing('run')}.\n"
    h, v = r["torque_horizontal_nm"], r["torque_vertical_nm"]
    rows = [
        "| `make run` (the default cut) | measured |", "|---|---|",
        f"| wall-clock, video included | {r['wall_clock_s']:.1f} s |",
        f"| simulated time | {r['duration_s']:.1f} s |",
        f"| completed | {'yes' if r['completed'] else 'no'} |",
        f"| stance: wall distance from the neck | {r['wall_distance_mm']:.0f} mm "
        f"({r['room_mm']:.0f} mm of room sideways) |",
        f"| bit error while cutting, RMS / max | {r['bit_rms_mm']:.2f} / "
        f"{r['bit_max_mm']:.2f} mm |",
        f"| hole in the wall, RMS (world, body sway included) | {r['hole_rms_mm']:.2f} mm |",
        f"| largest torso tilt | {r['max_tilt_deg']:.2f}° |",
        f"| smallest support margin | {r['min_support_margin_mm']:.1f} mm |",
        f"| wrist torque, horizontal edges, mean / max | {h[0]:.2f} / {h[1]:.2f} N m |",
        f"| wrist torque, vertical edges, mean / max | {v[0]:.2f} / {v[1]:.2f} N m "
        f"(limit {r['torque_limit_nm']:g}) |",
        f"| emergency stops, collision holds | {r['estop_events']}, {r['collision_holds']} |",
    ]
    if "status_counts" in r:
        counts = r["status_counts"]
        rows.append(f"| the status over the run's {sum(counts.values()):,} periods | "
                    + ", ".join(f"{n:,} {status}" for status, n in
                                sorted(counts.items(), key=lambda kv: -kv[1])) + " |")
    return "\n".join(rows) + f"\n\nM{_when(r)[1:]}.\n"


def page_walk(m: dict) -> str:
    w = m.get("walk")
    if not w:
        return f"`hubo walk --to 1.0 0 0`: {_missing('walk')}.\n"
    return (f"`hubo walk --to 1.0 0 0` (nominal robot): {'fell' if w['fell'] else 'did not fall'}, "
            f"{w['steps']} steps, final error {w['final_error_mm']:.1f} mm and "
            f"{w['final_error_deg']:.2f}°, {w['average_speed_m_s']:.3f} m/s on average, the ZMP "
            f"inside the support in {w['zmp_inside_percent']:.1f} % of periods"
            + (f" ({w['zmp_inside_raw_percent']:.1f} % from the unfiltered readings)"
               if "zmp_inside_raw_percent" in w else "") + "; "
            f"{w['wall_clock_s']:.0f} s of wall-clock ({_when(w)}).\n")


def page_suite(m: dict) -> str:
    s = m.get("suite")
    if not s:
        return f"The test suite: {_missing('suite')}.\n"
    return f"`make test`: {s['wall_clock_s']:.0f} s ({_when(s)}).\n"


def _arms(values: dict, fmt: str = "{:.1f}") -> str:
    """Per-hand figures, right first: "2.6 / 1.1" (right / left) or "4.8" (one hand)."""
    return " / ".join(fmt.format(values[a]) for a in ("right-arm", "left-arm") if a in values)


def page_teleop(m: dict) -> str:
    tele = m.get("teleop")
    if not tele:
        return f"The replays: {_missing('teleop')}.\n"
    rows = ["| `hubo teleop --replay trajectories/FILE --mode MODE` | hand(s) | position RMS "
            "(robot) | in the world | largest excursion | at reach limit | torso tilt | "
            "branch changes, e-stops, collision holds |",
            "|---|---|---|---|---|---|---|---|"]
    for r in tele["replays"]:
        hands = " / ".join(a.split("-")[0] for a in ("right-arm", "left-arm")
                           if a in r["position_rms_mm"])
        ended = "" if r["ended"] == "done" else f" (ended: {r['ended']})"
        rows.append(f"| `{r['replay']}`, {r['mode']}{ended} | {hands} | "
                    f"{_arms(r['position_rms_mm'])} mm | {_arms(r['world_rms_mm'])} mm | "
                    f"{_arms(r['max_excursion_mm'])} mm | {_arms(r['at_limit_s'])} s | "
                    f"{r['max_tilt_deg']:.2f}° | {r['branch_changes']}, {r['estop_events']}, "
                    f"{r['collision_holds']} |")
    return "\n".join(rows) + f"\n\nSimulated robot, default balancer; {_when(tele)}.\n"


def page_push(m: dict) -> str:
    push = m.get("push")
    if not push:
        return f"The pushes: {_missing('push')}.\n"
    rows = ["| 0.2 s push on the torso, 1 s into the run | outcome | steps | torso tilt, "
            "largest / at the end | soles moved | emergency stops |", "|---|---|---|---|---|---|"]
    for r in push["pushes"]:
        rows.append(f"| `{r['command']}` | {'fell' if r['fell'] else 'stood'} | {r['steps']} | "
                    f"{r['max_tilt_deg']:.1f}° / {r['final_tilt_deg']:.1f}° | "
                    f"{r['max_foot_shift_mm']:.1f} mm | {'; '.join(r['stops']) or 'none'} |")
    return ("\n".join(rows) + f"\n\nNominal simulated robot, default balancer, "
            f"{push['duration_s']:g} s of standing; {_when(push)}.\n")


def _bench_value(value: float) -> str:
    """As make bench prints it: three significant digits, thousands grouped."""
    return f"{value:,.3g}" if abs(value) < 1000 else f"{value:,.0f}"


def page_bench(m: dict) -> str:
    bench = m.get("bench")
    if not bench:
        return f"The benchmarks: {_missing('bench')}.\n"
    rows = ["| part | figure | measured | note |", "|---|---|---|---|"]
    for r in bench["rows"]:
        note = r["note"].replace("|", "\\|")
        unit = re.sub(r"^us\b", "µs", r["unit"])  # make bench prints ASCII
        rows.append(f"| {r['module']} | {r['name']} | {_bench_value(r['value'])} {unit} "
                    f"| {note} |")
    stopped = "".join(f"\n\n**`{f['module']}` stopped before its last figures:** "
                      f"`{f['error'][:300]}`" for f in bench.get("failures", []))
    return ("\n".join(rows) + f"\n\n`{bench['command']}`, {_when(bench)} (wall-clock "
            "figures on a busy machine are slower than on an idle one)." + stopped + "\n")


PAGES = {"install.md": page_install, "default-cut.md": page_default_cut, "walk.md": page_walk,
         "suite.md": page_suite, "teleop.md": page_teleop, "push.md": page_push,
         "bench.md": page_bench}


def load() -> dict:
    return json.loads(MEASURED.read_text()) if MEASURED.exists() else {}


def render(m: dict) -> None:
    GENERATED.mkdir(parents=True, exist_ok=True)
    MEASURED.write_text(json.dumps(m, indent=2, sort_keys=True) + "\n")
    for name, page in PAGES.items():
        (GENERATED / name).write_text(page(m))
    text = README.read_text()
    head, sep, rest = text.partition(README_BEGIN)
    _, sep2, tail = rest.partition(README_END)
    if not (sep and sep2):
        sys.exit(f"error: README.md has no {README_BEGIN!r} ... {README_END!r} block")
    README.write_text(f"{head}{README_BEGIN}\n{readme_block(m)}\n{README_END}{tail}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("parts", nargs="+", choices=[*PARTS, "render"])
    parser.add_argument("--warm-only", action="store_true",
                        help="install: skip the cold-cache install")
    args = parser.parse_args()
    m = load()
    for part in args.parts:
        print(f"measuring {part} ...", file=sys.stderr)
        if part == "run":
            m["run"] = measure_run()
        elif part == "walk":
            m["walk"] = measure_walk()
        elif part == "teleop":
            m["teleop"] = measure_teleop()
        elif part == "push":
            m["push"] = measure_push()
        elif part == "bench":
            m["bench"] = measure_bench()
        elif part == "install":
            m["install_warm"] = measure_install(cold=False)
            if not args.warm_only:
                m["install_cold"] = measure_install(cold=True)
        elif part == "suite":
            m["suite"] = measure_suite()
    render(m)
    shutil.rmtree(GENERATED / "__pycache__", ignore_errors=True)


if __name__ == "__main__":
    main()
