"""Options that several robot commands share."""

from __future__ import annotations

import click

perturb_option = click.option(
    "--perturb", "perturb_seed", type=click.IntRange(min=0), default=None, metavar="SEED",
    help="Simulate a robot and world drawn from SEED (masses, centres of mass, foot friction, "
         "sensor noise, command delay, floor tilt; 0 = nominal); the draws go into "
         "summary.json. Same seed, same run.")

BALANCE_HELP = ("Balance controllers: default (the ankle balancer's common and differential "
                "damping and what the balance pipeline adds), paper (eq. 11-12 as published, to "
                "study its lean) or off. Recorded in summary.json.")


def balance_option_with(default: str, note: str = ""):
    """``--balance {default,paper,off}`` with its own default (``note`` says why)."""
    return click.option("--balance", "balance", type=click.Choice(["default", "paper", "off"]),
                        default=default, show_default=True,
                        help=BALANCE_HELP + (f" {note}" if note else ""))


balance_option = balance_option_with("default")
