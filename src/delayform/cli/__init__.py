"""The ``delayform`` command line.

Every subcommand takes an optional scenario file (TOML, see
:mod:`delayform.scenario`; without one, the paper's example) and options that
override it, calls the library, writes figures (PNG and SVG), data (CSV and
NPZ) and summaries (JSON) into ``--out`` and prints a short summary, or the
summary as JSON on stdout with ``--json``. Progress goes to stderr.

Every input error (a bad option, a malformed scenario file, an argument the
library rejects) is one line on stderr naming the problem and exit code 2;
no traceback reaches the user for an input error.
"""

from __future__ import annotations

import sys
from typing import Any

import click

# the command modules register their commands on the group when imported
from delayform.cli import analysis, check, design, explore, gains, montecarlo, region, reports, simulation, sweep  # noqa: F401
from delayform.cli import guarantees  # noqa: F401  (issue 20)
from delayform.cli._common import _fail, cli
from delayform.errors import DelayformError, InputError

__all__ = ["cli", "main"]

# ------------------------------------------------------------------- entry
#: click >= 8.2 raises this for a group called without a command; older click prints help itself
_NO_ARGS_IS_HELP: Any = getattr(click.exceptions, "NoArgsIsHelpError", ())


def main(argv: list[str] | None = None) -> None:
    """Entry point of the console script: one line and exit code 2 for every input error.

    Parameters
    ----------
    argv
        The arguments after the program name; None reads ``sys.argv``.
    """
    try:
        code = cli.main(args=argv, prog_name="delayform", standalone_mode=False)
    except _NO_ARGS_IS_HELP as exc:  # plain `delayform`: show the help
        click.echo(exc.ctx.get_help() if exc.ctx is not None else str(exc))
        sys.exit(0)
    except click.UsageError as exc:  # bad option, missing value, bad parameter
        hint = f" (see: delayform {exc.ctx.info_name} --help)" if exc.ctx is not None and exc.ctx.parent else ""
        _fail(exc.format_message().replace("\n", " ") + hint)
    except click.ClickException as exc:
        _fail(exc.format_message().replace("\n", " "))
    except click.Abort as exc:
        # click turns Ctrl-C into Abort (after the blank line that ends the terminal's ^C echo)
        interrupted = isinstance(exc.__cause__, KeyboardInterrupt)
        click.echo("delayform: interrupted; files being written were discarded, earlier outputs are intact"
                   if interrupted else "delayform: aborted", err=True)  # fmt: skip
        sys.exit(130)
    except KeyboardInterrupt:  # outside click's own handling (e.g. while it prints)
        click.echo("delayform: interrupted; files being written were discarded, earlier outputs are intact", err=True)
        sys.exit(130)
    except InputError as exc:
        _fail(str(exc).replace("\n", " "))
    except DelayformError as exc:  # a computation that did not succeed: not the user's input
        _fail(str(exc).replace("\n", " "), code=1)
    except OSError as exc:  # e.g. an output file name taken by a folder, a full disk
        where = f" {exc.filename}" if exc.filename else ""
        _fail(f"cannot read or write{where}: {exc.strerror or exc}")
    except MemoryError:
        _fail("ran out of memory; make the job smaller (fewer agents, a smaller grid or window)", code=1)
    sys.exit(code if isinstance(code, int) else 0)
