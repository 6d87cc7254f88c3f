"""The ``delayform`` command line.

Every subcommand reports bad input as one line on stderr naming the problem
and exits with code 2; no traceback reaches the user for an input error.
"""

from __future__ import annotations

import sys

import click

from delayform.errors import InputError

TOPOLOGY_NAMES = ("paper_six", "ring", "complete", "star")


def _fail(message: str) -> None:
    click.echo(f"delayform: error: {message}", err=True)
    sys.exit(2)


def _named_topology(name: str, n: int):
    from delayform import topology as topo

    if name == "paper_six":
        return topo.paper_six()
    return getattr(topo, name)(n)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="delayform")
def cli() -> None:
    """delayform: exact stability maps, dominant roots, delay scheduling and
    simulation for robot formations under two communication delays."""


@cli.command("factors")
@click.option("--topology", "topology_name", type=click.Choice(TOPOLOGY_NAMES), default="paper_six",
              show_default=True, help="Named topology.")
@click.option("--n", type=int, default=6, show_default=True, help="Number of agents (not for paper_six).")
@click.option("--P", "P", type=float, default=1.0, show_default=True, help="Proportional gain P.")
@click.option("--D", "D", type=float, default=0.5, show_default=True, help="Derivative gain D.")
def factors_command(topology_name: str, n: int, P: float, D: float) -> None:
    """Print C, its eigenvalues and the factors of the characteristic equation (Lemma 1)."""
    import numpy as np

    from delayform.characteristic import factors

    try:
        topo = _named_topology(topology_name, n)
        fs = factors(topo, P, D)
    except InputError as exc:
        _fail(str(exc))
    with np.printoptions(precision=4, suppress=True, linewidth=120):
        click.echo(f"Topology {topo.name}: {topo.n} agents, spanning tree: {topo.has_spanning_tree()}")
        click.echo("C = Delta^-1 A =")
        click.echo(str(topo.C))
        click.echo("eigenvalues of C: " + ", ".join(f"{v:.4g}" for v in topo.eigenvalues))
    click.echo(f"Factors of the characteristic equation (eq. factorized), P = {P:g}, D = {D:g}:")
    for i, f in enumerate(fs, start=1):
        click.echo(f"  q{i}: {f.describe()}")
        click.echo(f"      {f.quasi_polynomial.describe()} = 0")


def main() -> None:
    """Entry point of the console script."""
    cli(prog_name="delayform")
