"""Run the manipulation experiments' cases (IV-C.2 of the multi-layer paper) and keep their plots
for the docs:

    python tools/manipulation_figures.py [--out DIR] [--perturb SEED] [--impedance]

Runs turn-valve and push-door on the nominal scene (with the stop) and each recognition error
with and without the stop (8 runs, about 10 s of CPU each), copies each run's
``manipulation.png`` to docs/figures/manipulation/ and prints the table of docs/history/
manipulation.md (the figures of this machine; the run folders stay under --out). With
``--impedance`` the right hand's ImpedanceController is on (the paper's was), and the plots
are not copied.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hubo_cli.experiments.manipulation import ManipulationSpec, run_manipulation  # noqa: E402
from hubo_cli.model import load_model  # noqa: E402

FIGURES = ROOT / "docs" / "figures" / "manipulation"
CASES = [  # (spec, estop)
    (ManipulationSpec("turn-valve"), True),
    (ManipulationSpec("push-door"), True),
    (ManipulationSpec("turn-valve", seen_offset_m=(0.131, 0.0, 0.033)), True),
    (ManipulationSpec("turn-valve", seen_offset_m=(0.131, 0.0, 0.033)), False),
    (ManipulationSpec("turn-valve", seen_offset_m=(0.0, 0.195, 0.0)), True),
    (ManipulationSpec("turn-valve", seen_offset_m=(0.0, 0.195, 0.0)), False),
    (ManipulationSpec("push-door", door_opens="toward"), True),
    (ManipulationSpec("push-door", door_opens="toward"), False),
]


def row(summary: dict) -> str:
    outcome = ("fell" if summary["fell"] else "tipped" if summary["tipped"] else "stayed up")
    if summary["overloaded"]:
        outcome += ", overloaded"
    if summary["wrist_overloaded"]:
        outcome += ", wrist overloaded"
    flag = summary["t_emergency_s"]
    return (f"| {summary['experiment']} | {summary['case']} | {summary['estop']} | "
            f"{'-' if flag is None else f'{flag:.2f} s'} | {summary['object_angle_deg']:.1f} | "
            f"{summary['max_cp_error_mm']:.0f} | {summary['max_axial_force_n']:.0f} | "
            f"{summary['max_wrist_moment_nm']:.1f} | {summary['wrist_over_limit_s']:.2f} s | "
            f"{summary['max_arm_torque_ratio'] * 100:.0f} % | {summary['max_tilt_deg']:.1f} | "
            f"{summary['end_tilt_deg']:.1f} | {summary['max_sole_lift_mm']:.0f} | "
            f"{summary['min_com_inside_mm']:.0f} | {outcome} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="where the run folders go")
    parser.add_argument("--perturb", type=int, default=None, help="a perturbed robot's seed")
    parser.add_argument("--impedance", action="store_true",
                        help="the right hand's ImpedanceController on")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="manipulation-"))
    model = load_model()
    FIGURES.mkdir(parents=True, exist_ok=True)
    print("| experiment | case | stop | flag | angle (deg) | max CP error (mm) | "
          "max wrist f_z (N) | max wrist moment (N m) | wrist beyond its limit | arm torque | "
          "max tilt (deg) | end tilt (deg) | sole lift (mm) | CoM inside soles (mm) | "
          "outcome |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for spec, estop in CASES:
        spec = replace(spec, impedance=args.impedance)
        name = f"{spec.kind}-{spec.case}-{'estop' if estop else 'no-estop'}"
        done = run_manipulation(model, spec, estop=estop, out=out / name,
                                perturb_seed=args.perturb)
        if args.perturb is None and not args.impedance:
            shutil.copy(done.run_dir / "manipulation.png", FIGURES / f"{name}.png")
        print(row(done.summary), flush=True)


if __name__ == "__main__":
    main()
