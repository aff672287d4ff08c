"""The ``rfsdf`` command: parses arguments, calls the library, turns bad input into one line."""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import click

from .errors import RfsdfError

__all__ = ["main"]


def _one_line_errors(func):
    """Show RfsdfError / ValueError as 'error: ...' with exit code 2, never a traceback."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except (RfsdfError, ValueError, OSError) as exc:
            click.echo(f"error: {exc}", err=True)
            sys.exit(2)

    return wrapper


@click.group()
@click.version_option(package_name="rfsdf")
def main():
    """rfsdf: neural SDF reconstruction from mmWave MIMO radar (GeRaF)."""


@main.group()
def scene():
    """Inspect scenes (presets or TOML files)."""


@scene.command("show")
@click.argument("name_or_file")
@click.option("--out", type=click.Path(path_type=Path), default=None,
              help="PNG of SDF slices (default: NAME-slices.png in the current folder).")
@_one_line_errors
def scene_show(name_or_file: str, out: Path | None):
    """Print a summary of a scene and write a picture of its SDF slices."""
    from .scene import load_scene
    from .viz import plot_sdf_slices

    sc = load_scene(name_or_file)
    click.echo(sc.summary())
    out = out or Path(f"{sc.name}-slices.png")
    plot_sdf_slices(sc.sdf, sc.lower_m, sc.upper_m, out, title=f"scene {sc.name!r}: SDF slices")
    click.echo(f"wrote {out}")


@main.command()
@click.option("--scene", "scene_name", default="objects", show_default=True, help="Scene preset or TOML file.")
@click.option("--out", type=click.Path(path_type=Path), default=Path("rfsdf-demo"), show_default=True)
@_one_line_errors
def demo(scene_name: str, out: Path):
    """Run the whole pipeline on the default scene and write every artefact to --out."""
    from .scene import load_scene
    from .viz import plot_sdf_slices

    sc = load_scene(scene_name)
    click.echo(sc.summary())
    path = plot_sdf_slices(sc.sdf, sc.lower_m, sc.upper_m, out / "scene-slices.png",
                           title=f"scene {sc.name!r}: SDF slices")
    click.echo(f"wrote {path}")
