"""Options that several robot commands share."""

from __future__ import annotations

import click

perturb_option = click.option(
    "--perturb", "perturb_seed", type=click.IntRange(min=0), default=None, metavar="SEED",
    help="Simulate a robot and world drawn from SEED (masses, centres of mass, foot friction, "
         "sensor noise, command delay, floor tilt; 0 = nominal); the draws go into "
         "summary.json. Same seed, same run.")
