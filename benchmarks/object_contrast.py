"""Which objects can a threshold on an image find at all? For each object of the default
demo, the view-mean amplitude (relative to its peak) on the voxels within 12 mm of that
object's surface, against the background: voxels more than 30 mm from every object, where
all that shows is the sidelobes of the strong reflectors. For the raw MF image and for its
CLEAN image (the warm start's), which removes those sidelobes.

Usage: python benchmarks/object_contrast.py [--out benchmarks/results/object_contrast.json]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch
from demo_data import demo_data

from rfsdf.jsonio import to_json
from rfsdf.radar.clean import clean_image

NEAR_M, FAR_M = 0.012, 0.03


def _summary(amplitude: torch.Tensor) -> dict:
    return {"max": float(amplitude.max()), "p99": float(amplitude.quantile(0.99)), "p90": float(amplitude.quantile(0.9)),
            "median": float(amplitude.median()), "voxels": len(amplitude)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/object_contrast.json"))
    args = parser.parse_args()

    data = demo_data()
    images = {"mf": data.image.power(), "clean": clean_image(data.measurements, data.image.grid).power}
    with torch.no_grad():
        distances = torch.stack([o.sdf(data.image.grid.points()) for o in data.scene.objects])  # (objects, N)
    nearest = distances.argmin(0)
    near = distances.min(0).values.abs() < NEAR_M
    result = {}
    for name, power in images.items():
        amplitude = power.flatten().clamp(min=0).sqrt()
        amplitude = amplitude / amplitude.max()
        result[name] = {"objects": {o.name: {"material": o.material.name, **_summary(amplitude[near & (nearest == i)])}
                                    for i, o in enumerate(data.scene.objects)},
                        "background": _summary(amplitude[distances.min(0).values > FAR_M])}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
