"""rfsdf's simulator against Sionna RT's ray tracer on the same walls: export each scene with
``rfsdf scene export``'s writer, compute Sionna's single-bounce specular channel for the same
Tx/Rx pair and frequencies (``sionna_paths.py``, run under a Python that has Sionna RT), and
compare with ``rfsdf.radar.simulate``: correlation after one complex gain, the range of the
strongest peak, and each material's amplitude relative to metal in each tool.

    python benchmarks/sionna_crosscheck.py --sionna-python /path/to/venv-with-sionna/bin/python

Sionna RT needs a recent libLLVM on the CPU (Debian 12: ``apt-get install libllvm19`` and
``DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so``). Writes
benchmarks/results/sionna-crosscheck.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from rfsdf.mitsuba.write import export_scene
from rfsdf.radar import simulate
from rfsdf.radar.acquisition import SPEED_OF_LIGHT
from rfsdf.radar.system import Radar
from rfsdf.scene import Scene
from rfsdf.scene_spec import SceneSpec

HERE = Path(__file__).parent
FREQUENCIES_HZ = np.linspace(26.5e9, 29.5e9, 256)  # room-28g's band; unambiguous range 12.8 m
MATERIALS = ["metal", "concrete", "glass", "plasterboard", "wood", "brick"]
THICKNESS_M = 0.1  # thick enough that the lossy slab is a half-space to Sionna's slab model
WALLS = {f"{m}-2x2m-at-1m": (m, (1.0, 1.0), 1.0) for m in MATERIALS} | {"concrete-4x3m-at-3m": ("concrete", (2.0, 1.5), 3.0)}


def _wall(material: str, half_m: tuple[float, float], distance_m: float) -> Scene:
    """A wall facing the radar at the origin (looking along +z), its near face at ``distance_m``."""
    centre = [0.0, 0.0, distance_m + THICKNESS_M / 2]
    margin = 0.2
    return Scene(SceneSpec.model_validate({
        "name": "wall",
        "bounds": {"lower_m": [-half_m[0] - margin, -half_m[1] - margin, distance_m - margin],
                   "upper_m": [half_m[0] + margin, half_m[1] + margin, distance_m + THICKNESS_M + margin]},
        "objects": [{"name": "wall", "material": material,
                     "shape": {"type": "box", "half_extents_m": [half_m[0], half_m[1], THICKNESS_M / 2],
                               "center_m": centre}}]}))


def _radar() -> Radar:
    """One Tx and one Rx 1 cm apart at the origin, isotropic, spreading on, noise-free."""
    return Radar("pair", np.array([[-0.005, 0.0, 0.0]]), np.array([[0.005, 0.0, 0.0]]), FREQUENCIES_HZ,
                 np.eye(3)[None], np.zeros((1, 3)), pattern_exponent=0.0, spreading=True, snr_db=None)


def _peak(h: np.ndarray) -> tuple[float, float]:
    """(one-way range [m], magnitude) of the strongest peak of the Hann-windowed profile."""
    n = 8 * len(h)
    profile = np.abs(np.fft.ifft(h * np.hanning(len(h)), n))
    spacing = FREQUENCIES_HZ[1] - FREQUENCIES_HZ[0]
    k = int(profile.argmax())
    return k * SPEED_OF_LIGHT / (spacing * n) / 2, float(profile[k])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sionna-python", required=True, help="a Python interpreter with sionna-rt installed")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "sionna-crosscheck.json")
    args = parser.parse_args()
    radar = _radar()
    acquisition = radar.acquisition()
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        pairs = Path(tmp) / "pairs.npz"
        np.savez(pairs, tx_m=acquisition.tx_m[0].numpy(), rx_m=acquisition.rx_m[0].numpy(),
                 frequencies_hz=FREQUENCIES_HZ)
        for name, (material, half, distance) in WALLS.items():
            scene = _wall(material, half, distance)
            start = time.perf_counter()
            h_rfsdf = simulate(scene, radar, seed=0, max_samples=3_000_000).data[0, 0, 0].numpy().astype(complex)
            rfsdf_s = time.perf_counter() - start
            xml = export_scene(scene, Path(tmp) / name)
            out = Path(tmp) / f"{name}-sionna.npz"
            start = time.perf_counter()
            subprocess.run([args.sionna_python, str(HERE / "sionna_paths.py"), str(xml), str(pairs), str(out)],
                           check=True)
            sionna_s = time.perf_counter() - start
            h_sionna = np.load(out)["h"][0]
            correlation = abs(np.vdot(h_sionna, h_rfsdf)) / (np.linalg.norm(h_sionna) * np.linalg.norm(h_rfsdf))
            (r_rfsdf, a_rfsdf), (r_sionna, a_sionna) = _peak(h_rfsdf), _peak(h_sionna)
            rows[name] = {"material": material, "distance_m": distance, "correlation": round(float(correlation), 4),
                          "peak_range_m": {"rfsdf": round(r_rfsdf, 4), "sionna": round(r_sionna, 4)},
                          "peak_amplitude": {"rfsdf": a_rfsdf, "sionna": a_sionna},
                          "time_s": {"rfsdf": round(rfsdf_s, 1), "sionna": round(sionna_s, 1)}}
            print(name, rows[name], flush=True)
    metal = rows["metal-2x2m-at-1m"]["peak_amplitude"]
    for row in rows.values():
        row["relative_to_metal"] = {tool: round(row["peak_amplitude"][tool] / metal[tool], 4) for tool in metal}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"frequencies_ghz": [26.5, 29.5, len(FREQUENCIES_HZ)], "walls": rows}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
