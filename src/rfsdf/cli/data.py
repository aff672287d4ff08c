"""Measurements made and imaged: rfsdf simulate, image, calibrate."""

from __future__ import annotations

from pathlib import Path

import click

from .app import (
    BATCH_EXIT,
    BOUNDS_HELP,
    device_named,
    device_option,
    exit_on_failures,
    image_box,
    main,
    one_line_errors,
    POSITIVE,
    RAY_HELP,
    refuse_overwriting_inputs,
    SEED,
    voxel_size,
)


def _simulate(scene_name: str, radar_name: str, seed: int, device, max_samples: int = 150_000,
              surface: str = "facets", transmission: bool = False):
    from ..radar import check_materials_in_band, check_radar_for_scene, load_radar, simulate
    from ..scene import load_scene

    rad = load_radar(radar_name)
    sc = load_scene(scene_name).around_radar(rad.positions_m)
    check_radar_for_scene(rad, sc.lower_m, sc.upper_m, source=radar_name)
    check_materials_in_band(sc, rad, source=scene_name)
    click.echo(sc.summary())
    click.echo(rad.summary())
    measurements = simulate(sc, rad, seed=seed, device=device, max_samples=max_samples, surface=surface,
                            transmission=transmission, progress=True)
    click.echo(measurements.metadata["surface_sampling"])
    return sc, measurements


def _image(measurements, lower_m, upper_m, voxel_m: float, out_image: Path, out_png: Path, method: str, device):
    from ..geometry import Grid
    from ..radar import matched_filter
    from ..radar.imaging import imaging_method, require_image_memory
    from ..radar.scan_imaging import lattice_grid, planar_scan, scan_matched_filter, scan_views_matched_filter

    acq = measurements.acquisition
    grid = Grid.from_voxel(lower_m, upper_m, voxel_m)
    count = f"({acq.num_measurements} measurements)"
    if method in ("auto", "scan"):
        try:
            if acq.scans is not None:  # one view a scan: each by FFT on the lattice they share
                scan = planar_scan(acq.coherent_view(0))[0]
                image = scan_views_matched_filter(measurements, lattice_grid(acq, lower_m, upper_m), device=device)
            else:
                raster = planar_scan(acq)
                scan, image = raster[0], scan_matched_filter(measurements, grid, raster=raster, device=device)
        except ValueError as exc:
            if method == "scan":
                raise ValueError(f"--method scan: {exc}") from None
        else:
            step = image.grid.voxel_m
            click.echo(f"matched filter of {acq.num_views} x a {scan.shape[0]} x {scan.shape[1]} raster scan "
                       f"({scan.steps_m[0] * 1e3:.3g} x {scan.steps_m[1] * 1e3:.3g} mm steps) {count}, each one coherent "
                       f"view, by FFT on the raster's lattice ({step[0] * 1e3:.3g} x {step[1] * 1e3:.3g} x "
                       f"{step[2] * 1e3:.3g} mm voxels) on {device}")
            return _write_image(image, out_image, out_png, "matched-filter power (each scan coherent)")
    require_image_memory(acq.num_views, grid)
    chosen = imaging_method(acq, method, device)
    why = {"fast": "range-profile back-projection", "exact": "the sensing operator's adjoint"}[chosen]
    click.echo(f"matched filter on {grid.shape} voxels of {voxel_m * 1e3:.2f} mm {count}: {chosen} ({why}"
               f"{', chosen by --method auto' if method == 'auto' else ''}) on {device}")
    image = matched_filter(measurements, grid, method=chosen, device=device, progress=True)
    return _write_image(image, out_image, out_png, "matched-filter power (mean over views)")


def _write_image(image, out_image: Path, out_png: Path, title: str):
    from ..radar import write_image
    from ..viz import plot_mip

    write_image(out_image, image)
    plot_mip(image.power().numpy(), image.grid.lower_m, image.grid.upper_m, out_png, title=title)
    click.echo(f"wrote {out_image} and {out_png}")
    return image


@main.command("simulate", epilog="With --random: " + BATCH_EXIT)
@click.argument("scene_name", required=False)
@click.option("--radar", "radar_name", default="near-77g", show_default=True, help="Radar preset or TOML file.")
@click.option("--out", type=click.Path(path_type=Path), required=True,
              help="Measurements file (.h5); with --random a dataset folder.")
@click.option("--seed", type=SEED, default=0, show_default=True,
              help="Noise and sampling seed (0 to 2^32-1); with --random the first scene's seed.")
@click.option("--random", "random_count", type=click.IntRange(1, 10**6), default=None,
              help="Instead of SCENE_NAME: this many seeded random scenes, each a scene file + measurements.")
@click.option("--workers", type=click.IntRange(1, 1024), default=1, show_default=True,
              help="With --random: scenes at once in a local process pool.")
@click.option("--ray", "ray_address", is_flag=False, flag_value="local", default=None, help=RAY_HELP)
@click.option("--max-samples", type=click.IntRange(1, 10**8), default=150_000, show_default=True,
              help="Most surface samples: the surface on lambda/3 cells when points that far apart would fit, "
                   "else facets sized to their range (a room), else refused with the count it needs.")
@click.option("--surface", type=click.Choice(["facets", "points"]), default="facets", show_default=True,
              help="How the surface is summed: flat facets of its zero set with their phase integrated (converged), "
                   "or points (a Monte Carlo quadrature, for comparison).")
@click.option("--transmission", is_flag=True,
              help="Lines of sight go on through dielectric objects (each a slab of the chord it cuts: ITU-R P.2040's "
                   "T out and back at every frequency); metal still blocks. Default: opaque objects.")
@device_option()
@one_line_errors
def simulate_cmd(scene_name: str | None, radar_name: str, out: Path, seed: int, random_count: int | None,
                 workers: int, ray_address: str | None, max_samples: int, surface: str, transmission: bool,
                 device: str):
    """Simulate radar measurements of a scene and write them to an HDF5 file, or (--random N)
    a dataset of N random scenes: OUT/scene-NNNNN.toml + .h5 and OUT/dataset.json."""
    if (scene_name is None) == (random_count is None):
        raise ValueError("give a SCENE_NAME or --random N (not both)")
    if random_count is not None and transmission:
        raise ValueError("--transmission: random datasets are simulated opaque; give a SCENE_NAME")
    if random_count is not None:
        from ..dataset import check_dataset, simulate_dataset

        device_named(device)  # refuse a device this machine lacks before any scene is drawn
        refuse_overwriting_inputs(out, radar_name)
        click.echo(check_dataset(random_count, out, radar=radar_name, base_seed=seed))
        rows = simulate_dataset(random_count, out, radar=radar_name, base_seed=seed, workers=workers,
                                ray_address=ray_address, device=device, log=click.echo)
        failed = sum(row["status"] == "failed" for row in rows)
        click.echo(f"wrote {out / 'dataset.json'} ({len(rows) - failed} scenes, {failed} failed)")
        exit_on_failures(failed)
        return
    from ..radar import write_measurements

    refuse_overwriting_inputs(out, scene_name, radar_name)
    _, measurements = _simulate(scene_name, radar_name, seed, device_named(device), max_samples, surface,
                                transmission)
    write_measurements(out, measurements)
    click.echo(f"wrote {out}")


@main.command("image")
@click.argument("data", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, help="Image file (.h5); MIPs go beside it.")
@click.option("--voxel", "voxel_m", type=POSITIVE, default=None, help="Voxel size [m] (default: box extent / 64).")
@click.option("--bounds", default=None, help=BOUNDS_HELP)
@click.option("--scene", "scene_name", default=None, help="Scene whose bounds to image.")
@click.option("--method", type=click.Choice(["auto", "exact", "fast", "scan"]), default="auto", show_default=True,
              help="exact adjoint, fast range-profile back-projection, or scan: views that are one board's positions "
                   "on a planar raster imaged as one coherent view by FFT, on the raster's lattice (auto: scan where "
                   "the views form a raster, else fast from 32 frequencies on a CPU, else exact).")
@device_option()
@one_line_errors
def image_cmd(data: Path, out: Path, voxel_m: float | None, bounds: str | None, scene_name: str | None, method: str,
              device: str):
    """Matched-filter image of a measurements file, plus maximum-intensity projections (PNG)."""
    from ..radar import read_measurements

    device = device_named(device)
    refuse_overwriting_inputs(out, data, scene_name)
    refuse_overwriting_inputs(out.with_suffix(".mip.png"), data, scene_name)
    measurements = read_measurements(data)
    lower, upper = image_box(data, measurements, bounds, scene_name)
    _image(measurements, lower, upper, voxel_size(voxel_m, lower, upper), out, out.with_suffix(".mip.png"), method, device)


@main.command("calibrate")
@click.argument("capture", type=click.Path(path_type=Path))
@click.option("--scene", "scene_name", required=True,
              help="The capture's scene: the known target (a metal sphere or plate) where it stood, with its material.")
@click.option("--out", type=click.Path(path_type=Path), required=True, help="The gain file (JSON) reconstruct --gain reads.")
@one_line_errors
def calibrate_cmd(capture: Path, scene_name: str, out: Path):
    """Measure the radar's gain from CAPTURE, a capture of a known target: against the
    simulator's noise-free data of --scene through the capture's own antennas, frequencies
    and views. `reconstruct --gain OUT` then reads materials absolutely from data of the same
    radar and settings (rfsdf.radar.capture_gain)."""
    from ..jsonio import write_json
    from ..radar import read_measurements
    from ..radar.capture_gain import capture_gain
    from ..scene import load_scene

    refuse_overwriting_inputs(out, capture, scene_name)
    measured = capture_gain(read_measurements(capture), load_scene(scene_name), capture_name=str(capture))
    write_json(out, measured.as_dict())
    click.echo(f"gain {measured.gain:.6g} (scene {measured.scene!r} explains {measured.explained:.1%} of the "
               f"capture's energy); wrote {out}")
