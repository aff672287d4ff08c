"""The primitive fit of a room to its range profiles, over start seeds, scored where the data see.

The room (default ``l-room`` by ``room-60g``) is simulated once (facets; about 8 min on 2
cores) unless ``--data`` names measurements that exist (else they are written there). Then, per seed, the model is the true scene
with every length free and moved by up to ``--start-offset`` (``SceneModel.from_scene``) and
fitted by ``fit_primitive_profiles``. The score is the surface the data see: the **specular
foot points**, hits of rays from every view on the true surfaces within 1.8 deg of normal
incidence (one per 10 cm cell per view), and the start's and the fitted model's |f| there
[m]. (Per-parameter errors mislead on a CSG room: faces no view sees, and coincident faces
of which only one is a surface, have parameters no data move.)

With ``--beams`` each view's profiles are compared per beam of its array
(``ProfileSettings.beams``), not as the mean over its channels.

Usage: python benchmarks/room_fit.py [--data lroom.h5] [--seeds 0 1 2] [--steps 150] [--beams]
       [--out benchmarks/results/room-fit-l-room.json]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from rfsdf.jsonio import to_json
from rfsdf.metrics import specular_feet
from rfsdf.radar import load_radar, read_measurements, simulate, write_measurements
from rfsdf.recon.range_profile import ProfileSettings, fit_primitive_profiles
from rfsdf.scene import Scene, load_scene
from rfsdf.scene_model import SceneModel

def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default="l-room")
    parser.add_argument("--radar", default="room-60g")
    parser.add_argument("--data", type=Path, default=None,
                        help="the room's measurements (simulated and written there if the file does not exist)")
    parser.add_argument("--beams", action="store_true", help="fit the profiles per beam (ProfileSettings.beams)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--steps", type=int, default=150)
    parser.add_argument("--start-offset", type=float, default=0.15)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/room-fit-{Path(args.scene).stem}{'-beams' if args.beams else ''}.json")
    truth = load_scene(args.scene)
    if args.data is not None and args.data.is_file():
        data = read_measurements(args.data)
    else:
        clock = time.perf_counter()
        data = simulate(truth, load_radar(args.radar), max_samples=3_000_000, progress=True)
        print(f"simulated in {time.perf_counter() - clock:.0f} s")
        if args.data is not None:
            write_measurements(args.data, data)
    feet = specular_feet(truth, data.acquisition)
    runs = []
    for seed in args.seeds:
        model = SceneModel.from_scene(truth, args.start_offset, seed)
        fit = fit_primitive_profiles(data, model, steps=args.steps, settings=ProfileSettings(beams=args.beams))
        fitted = Scene(fit.fitted_spec())
        start_error = Scene(model.spec).sdf(feet).abs()
        error = fitted.sdf(feet).abs()
        runs.append({"seed": seed, "fit_s": round(fit.seconds, 1), "start_mean_m": float(start_error.mean()),
                     "fitted_mean_m": float(error.mean()), "fitted_median_m": float(error.median()),
                     "within_1cm": float((error < 0.01).double().mean()), "fitted_m": error.tolist()})
        print(f"seed {seed}: {fit.seconds:.0f} s, start {start_error.mean() * 100:.1f} cm -> fitted "
              f"{error.mean() * 100:.2f} cm, within 1 cm {runs[-1]['within_1cm']:.0%} of {len(feet)} foot points")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json({"scene": args.scene, "radar": args.radar, "steps": args.steps, "beams": args.beams,
                            "start_offset_m": args.start_offset, "foot_points": feet.tolist(), "runs": runs}))


if __name__ == "__main__":
    main()
