"""Sionna RT's specular channel for rfsdf's Tx/Rx pairs; run by ``sionna_crosscheck.py`` and
``sionna_slab.py`` under a Python that has Sionna RT (never rfsdf's own: Sionna is not one
of its dependencies).

    python sionna_paths.py SCENE.xml PAIRS.npz OUT.npz [--max-depth N] [--refraction]

PAIRS.npz: tx_m (P, 3), rx_m (P, 3) [m], frequencies_hz (K,). OUT.npz: h (P, K) complex, the
sum over specular paths (no line of sight, no diffuse part, no diffraction, isotropic
antennas, one polarisation) of a_i exp(-j 2 pi (f - fc) tau_i), a_i taken at the band centre
fc as Sionna gives them. By default single-bounce reflections only (max depth 1, no
refraction); ``--refraction`` lets rays pass through each surface as Sionna's slab of its
material's thickness (a reflection behind a sheet is depth 3: through, back, through).
"""

import argparse

import mitsuba as mi  # noqa: F401 - Sionna picks its variant on import
import numpy as np
import sionna.rt as rt


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene_file")
    parser.add_argument("pairs_file")
    parser.add_argument("out_file")
    parser.add_argument("--max-depth", type=int, default=1)
    parser.add_argument("--refraction", action="store_true")
    args = parser.parse_args()
    pairs = np.load(args.pairs_file)
    frequencies = pairs["frequencies_hz"]
    scene = rt.load_scene(args.scene_file)
    scene.frequency = float(frequencies.mean())
    array = dict(num_rows=1, num_cols=1, vertical_spacing=0.5, horizontal_spacing=0.5, pattern="iso",
                 polarization="V")
    scene.tx_array, scene.rx_array = rt.PlanarArray(**array), rt.PlanarArray(**array)
    solver = rt.PathSolver()
    h = np.zeros((len(pairs["tx_m"]), len(frequencies)), dtype=complex)
    for p, (tx, rx) in enumerate(zip(pairs["tx_m"], pairs["rx_m"])):
        scene.add(rt.Transmitter(f"tx{p}", position=[float(v) for v in tx]))
        scene.add(rt.Receiver(f"rx{p}", position=[float(v) for v in rx]))
        paths = solver(scene, max_depth=args.max_depth, los=False, specular_reflection=True,
                       diffuse_reflection=False, refraction=args.refraction, synthetic_array=False)
        cfr = paths.cfr(frequencies=frequencies - scene.frequency, normalize_delays=False, out_type="numpy")
        h[p] = np.asarray(cfr).reshape(-1, len(frequencies))[0]
        scene.remove(f"tx{p}")
        scene.remove(f"rx{p}")
    np.savez(args.out_file, h=h)


if __name__ == "__main__":
    main()
