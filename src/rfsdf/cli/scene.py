"""rfsdf scene show|export."""

from __future__ import annotations

from pathlib import Path

import click

from .app import main, one_line_errors, refuse_overwriting_inputs


@main.group()
def scene():
    """Inspect and export scenes (presets, TOML files or Sionna RT / Mitsuba XML files)."""


@scene.command("show")
@click.argument("name_or_file")
@click.option("--out", type=click.Path(path_type=Path), default=None,
              help="PNG of SDF slices (default: NAME-slices.png in the current folder).")
@one_line_errors
def scene_show(name_or_file: str, out: Path | None):
    """Print a summary of a scene and write a picture of its SDF slices."""
    from ..scene import load_scene
    from ..viz import plot_sdf_slices

    sc = load_scene(name_or_file)
    out = out or Path(f"{sc.name}-slices.png")
    refuse_overwriting_inputs(out, name_or_file)
    click.echo(sc.summary())
    plot_sdf_slices(sc.sdf, sc.lower_m, sc.upper_m, out, title=f"scene {sc.name!r}: SDF slices")
    click.echo(f"wrote {out}")


@scene.command("export")
@click.argument("name_or_file")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Folder to write scene.xml and meshes/*.ply into (not the scene's own folder).")
@one_line_errors
def scene_export(name_or_file: str, out: Path):
    """Write a scene as a Sionna RT / Mitsuba 3 scene: OUT/scene.xml and OUT/meshes/*.ply."""
    from ..mitsuba.write import export_scene
    from ..scene import load_scene

    sc = load_scene(name_or_file)
    if Path(name_or_file).is_file() and out.exists() and out.resolve() == Path(name_or_file).resolve().parent:
        raise ValueError(f"{out}: --out is the folder of the input {name_or_file}; exporting there could replace "
                         "its meshes, choose another folder")
    path = export_scene(sc, out)
    click.echo(f"wrote {path} and {len(sc.objects)} mesh(es) in {path.parent / 'meshes'}")
