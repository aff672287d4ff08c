"""The ``rfsdf`` group and what its commands share: one-line errors, the device option, the box to image."""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import click

from ..errors import RfsdfError
from ..progress import set_quiet

__all__ = ["main", "one_line_errors", "refuse_overwriting_inputs", "device_option", "device_named", "exit_on_failures",
           "image_box", "voxel_size", "POSITIVE", "SEED", "BATCH_EXIT", "RAY_HELP", "BOUNDS_HELP"]


def one_line_errors(func):
    """Show RfsdfError / ValueError as 'error: ...' with exit code 2, never a traceback."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except (RfsdfError, ValueError, OSError) as exc:
            click.echo(f"error: {exc}", err=True)
            sys.exit(2)

    return wrapper


def refuse_overwriting_inputs(out: Path, *inputs) -> None:
    """ValueError when ``out`` is (or would replace) one of the command's input files."""
    import os

    for given in inputs:
        if given is None or not Path(given).exists() or not out.exists():
            continue
        if os.path.samefile(out, given):
            raise ValueError(f"{out}: --out is the input {given}; writing it would destroy the input, "
                             "choose another output")


class _PositiveFinite(click.ParamType):
    """A float > 0 that is finite (click's FloatRange lets nan and inf through)."""

    name = "positive number"

    def convert(self, value, param, ctx):
        import math

        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not (math.isfinite(number) and number > 0):
            self.fail(f"{value!r} is not a positive, finite number", param, ctx)
        return number


POSITIVE = _PositiveFinite()
SEED = click.IntRange(0, 2**32 - 1)


class _OneLineGroup(click.Group):
    """Click's own usage errors (bad option values, unknown options) as one 'error:' line
    with exit code 2, the same promise the commands keep, instead of a usage block."""

    def main(self, *args, standalone_mode: bool = True, **kwargs):
        try:
            return super().main(*args, standalone_mode=False, **kwargs)
        except click.exceptions.Abort:
            click.echo("error: aborted", err=True)
            sys.exit(1)
        except click.exceptions.NoArgsIsHelpError as exc:  # a bare group name: its help, as click does
            click.echo(exc.format_message(), err=True)
            sys.exit(2)
        except click.ClickException as exc:
            click.echo(f"error: {exc.format_message()}", err=True)
            sys.exit(2)


def _checkout_commit() -> str | None:
    """``git describe --always --dirty`` (tags excluded: the commit) of the checkout this package runs from, or None
    (an installed wheel, no git, or git failing)."""
    import subprocess

    root = Path(__file__).resolve().parents[3]
    if not (root / ".git").exists():
        return None
    try:
        described = subprocess.run(["git", "-C", str(root), "describe", "--always", "--dirty", "--abbrev=12",
                                    "--exclude", "*"], capture_output=True, text=True, timeout=5, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return described.stdout.strip() or None


def _print_version(ctx: click.Context, _param, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    from .. import __version__

    commit = _checkout_commit()
    click.echo(f"rfsdf {__version__}" + ("" if commit is None else f" (commit {commit})"))
    ctx.exit()


@click.group(cls=_OneLineGroup)
@click.option("--version", is_flag=True, expose_value=False, is_eager=True, callback=_print_version,
              help="Show the version (and the commit, when run from a git checkout) and exit.")
@click.option("--quiet", is_flag=True, help="No progress bars (results and errors still print).")
def main(quiet: bool):
    """rfsdf: neural SDF reconstruction from mmWave MIMO radar (GeRaF).

    Progress bars go to stderr; in a log (stderr not a terminal) they become a plain line
    every 30 s of a long stage."""
    set_quiet(quiet)


def device_option(default: str | None = "auto", text: str = "Where the tensors live: auto (CUDA when there is a GPU), cpu or cuda[:N]."):
    return click.option("--device", default=default, show_default=default is not None, help=text)


def device_named(name: str | None):
    from ..device import resolve_device

    return resolve_device(name)


def exit_on_failures(failed: int) -> None:
    """Exit status 1 when some of a batch's jobs failed (they are rows of its summary), so
    that `rfsdf sweep ... && next-step` and a cluster's job runner notice."""
    if failed:
        sys.exit(1)


BATCH_EXIT = ("Exit status: 0 when every job finished, 1 when some failed (each failure is a row of the summary "
               "with its error line), 2 when the input was refused before any job ran.")


RAY_HELP = "Run as Ray tasks: bare --ray starts a local Ray instance, --ray ADDRESS joins a cluster."


def image_box(data: Path, measurements, bounds: str | None, scene_name: str | None):
    """The box to image, from --bounds, else the bounds stored in the file, else a scene's."""
    from ..radar import parse_bounds
    from ..scene import load_scene

    if bounds is not None:
        return parse_bounds(bounds, "--bounds")
    if scene_name is None and "bounds_m" in measurements.metadata:
        return parse_bounds(measurements.metadata["bounds_m"], f"{data}: meta_bounds_m")
    name = scene_name or measurements.metadata.get("scene")
    if name is None:
        raise ValueError(f"{data}: no bounds or scene recorded in the file; pass --bounds XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX")
    sc = load_scene(name)
    return tuple(sc.lower_m), tuple(sc.upper_m)


def voxel_size(voxel_m: float | None, lower, upper, voxels_per_edge: int = 64) -> float:
    """--voxel, or the box's longest edge / ``voxels_per_edge`` when unset."""
    import numpy as np

    return float(np.max(np.subtract(upper, lower))) / voxels_per_edge if voxel_m is None else voxel_m


BOUNDS_HELP = "Box to image [m], XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (default: the bounds stored in DATA, else --scene's)."
