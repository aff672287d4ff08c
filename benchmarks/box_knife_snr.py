"""Sionna RT's ``box_knife`` through ``rfsdf demo --model primitive --transmission`` at
more than the radar's SNR, on the same simulation: where each wall of the room ends.

The simulator sets the noise at ``snr_db`` under the mean received power, and on
``box_knife`` that power is the glass knife's, 4-13 cm from the arrays and some 60 dB over a
wall 5 m away; at room-28g's 20 dB the walls seen through the knife stand 4-6 dB over the
noise in their views' range profiles. This script takes a finished run's data, takes the
noise out (regenerated from the run's seed, as :func:`rfsdf.radar.simulate.add_noise` drew
it: the clean data's sigma is checked against the stored one), puts it back scaled to each
SNR, and runs the same fit on each (its start, steps and rays), 2-3 min a fit on 2 cores.
With ``--noise-seeds`` the noise put back is also drawn afresh from other seeds (the run's
own seed is the simulator's draw), so a wall a few dB over the noise is scored over draws.

    rfsdf demo --scene box_knife.xml --radar room-28g --model primitive --max-samples 6000000 \\
        --transmission --out RUN                   # the simulation: 1 h 49 min on 2 cores
    python benchmarks/box_knife_snr.py --run RUN   # -> benchmarks/results/box-knife-snr.json
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import math
import shutil
from pathlib import Path

import torch

from rfsdf.demo import claim_folder, load_scene_and_radar
from rfsdf.model_demo import ModelDemoSettings, run_model_demo
from rfsdf.radar import read_measurements, write_measurements
from rfsdf.radar.simulate import noise_draw
from rfsdf.recon.neural_profiles import NeuralProfileSettings

HERE = Path(__file__).parent
WALLS = ("x = -5 m", "y = -5 m", "floor", "x = +5 m", "y = +5 m", "ceiling")
THROUGH_THE_KNIFE = ("x = -5 m", "x = +5 m")  # the views at x = +-0.3 m look through its two slopes


def unit_noise(measurements, seed: int) -> torch.Tensor:
    """The noise at unit sigma that :func:`rfsdf.radar.simulate.add_noise` draws for a run
    of ``seed`` (from ``seed`` + 1, as the simulator seeds it), shaped as the data."""
    draw = noise_draw(measurements.data.shape, torch.Generator().manual_seed(seed + 1))
    return draw.to(measurements.data.dtype) / math.sqrt(2)


def walls(row: dict, which: str = "fitted") -> dict[str, float]:
    """Each inner wall's position [m] (the shell's inner box, children[1]) where the fit
    ended (``which`` "fitted") or began ("start")."""
    half, centre = (next(f[which] for f in row["free"] if f["name"] == f"box.children[1].{key}")
                    for key in ("half_extents_m", "center_m"))
    sides = [c - h for c, h in zip(centre, half)] + [c + h for c, h in zip(centre, half)]
    return dict(zip(WALLS, sides))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, required=True, help="a finished box_knife demo --model primitive --transmission")
    parser.add_argument("--snr-db", type=float, nargs="+", default=[20.0, 30.0, 40.0])
    parser.add_argument("--noise-seeds", type=int, nargs="+", default=None,
                        help="the noise put back drawn from these seeds as add_noise would (default: the run's own)")
    parser.add_argument("--beams", action="store_true",
                        help="fit each view's profiles per beam of its array (ModelDemoSettings.beams)")
    parser.add_argument("--work", type=Path, default=None, help="where the runs at each SNR go (default RUN-snr)")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "box-knife-snr.json")
    args = parser.parse_args()
    held = json.loads((args.run / "demo-settings.json").read_text())
    settings = ModelDemoSettings(**{**held, "neural": NeuralProfileSettings(**held["neural"])})
    settings = dataclasses.replace(settings, beams=args.beams or settings.beams)
    measurements = read_measurements(args.run / "measurements.h5")
    clean = measurements.data - measurements.noise_std * unit_noise(measurements, settings.seed)
    sigma = math.sqrt(float((clean.abs() ** 2).mean()))  # the clean data's rms
    radar_db = load_scene_and_radar(settings.scene, settings.radar).radar.snr_db
    if abs(20 * math.log10(sigma / measurements.noise_std) - radar_db) > 1e-3:  # add_noise set sigma from the clean data
        raise SystemExit(f"{args.run}: the regenerated noise is not this run's (the clean data would stand "
                         f"{20 * math.log10(sigma / measurements.noise_std):.4f} dB over it, not {radar_db:g})")
    work = args.work or args.run.with_name(args.run.name + "-snr")
    truth = {"x = -5 m": -5.0, "y = -5 m": -5.0, "floor": 0.0, "x = +5 m": 5.0, "y = +5 m": 5.0, "ceiling": 5.0}
    rows = []
    for noise_seed, target_db in itertools.product(args.noise_seeds or [settings.seed], args.snr_db):
        folder = work / (f"{target_db:g}db" + ("" if noise_seed == settings.seed else f"-noise{noise_seed}")
                         + ("-beams" if settings.beams else ""))
        draw = unit_noise(measurements, noise_seed)
        noise_std = sigma / 10 ** (target_db / 20)
        if not (folder / "metrics.json").is_file():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir(parents=True)
            claim_folder(folder, settings)  # the run's settings: the demo then reads these data
            write_measurements(folder / "measurements.h5", dataclasses.replace(
                measurements, data=clean + noise_std * draw, noise_std=noise_std))
        result = run_model_demo(folder, settings, ("primitive",), log=lambda _: None, progress=False)
        row = result["models"]["primitive"]
        ends = walls(row)
        seen = row["seen_surface"]["objects"]["box"]
        rows.append({"snr_db": target_db, "noise_seed": noise_seed, "beams": settings.beams, "start_off_mm": {k: abs(v - truth[k]) * 1e3 for k, v in walls(row, "start").items()},
                     "walls_m": ends, "off_mm": {k: abs(v - truth[k]) * 1e3 for k, v in ends.items()},
                     "feet_within": seen["within"], "feet_median_mm": seen["median_mm"],
                     "chamfer_l1_mm": row["chamfer_l1_mm"], "fit_s": row["fit_s"]})
        off = rows[-1]["off_mm"]
        print(f"{target_db:g} dB, noise seed {noise_seed}: " + ", ".join(f"{k} {off[k]:.1f} mm" for k in WALLS)
              + f"; feet within 25 mm {seen['within']:.0%}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({
        "what": "box_knife's walls after demo --model primitive --transmission, the same simulation at each SNR",
        "run": str(args.run), "seed": settings.seed, "start_offset_m": settings.start_offset_m,
        "through_the_knife": THROUGH_THE_KNIFE, "truth_m": truth, "rows": rows}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
