"""rfsdf's transmission against Sionna RT's refraction: a metal plate behind a dielectric
sheet, each catalogue material P.2040 and Sionna both define over 57-64 GHz, seen at normal
incidence by one Tx/Rx pair over room-60g's band. Both tools get the same scene (``rfsdf
scene export``'s writer: the sheet an open rectangle with its material's thickness, as
Sionna's own walls are); Sionna's channel is the sum of its specular paths to depth 3 with
refraction (the sheet's reflection, and through it, off the plate and back through it:
``sionna_paths.py --refraction``), rfsdf's its facet simulation with ``transmission=True``.

Each return is range-gated (the Hann-windowed range profile within 15 cm of the plate or of
the sheet; the two stand 40 cm, 19 range cells, apart): per material its peak over the bare
plate's in each tool against P.2040's |T|^2 and |R|, where each tool puts the plate, and the
correlation of the two tools' gated profiles after one complex gain. Sionna's path delays
are geometric (its sheet has no thickness, and T carries the slab's whole phase at the
band's centre), so its plate stands where the bare one did; the correlation is also given
with Sionna's channel delayed by the slab's two-way excess path, the one convention apart,
and the whole channels' correlation beside the one those conventions leave between the
sheet's and the plate's paths (``channel_correlation_conventions``, from the gated peaks).

    python benchmarks/sionna_slab.py --sionna-python /path/to/venv-with-sionna/bin/python

Sionna RT needs a recent libLLVM on the CPU (see ``sionna_crosscheck.py``). Writes
benchmarks/results/sionna-slab.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from rfsdf.materials import get_material
from rfsdf.mitsuba.write import export_scene
from rfsdf.radar import simulate
from rfsdf.radar.acquisition import SPEED_OF_LIGHT
from rfsdf.radar.system import Radar
from rfsdf.scene import Scene
from rfsdf.scene_spec import SceneSpec
from rfsdf.slab import excess_path, slab_coefficients

HERE = Path(__file__).parent
TOOLS = ("rfsdf", "sionna")
FREQUENCIES_HZ = np.linspace(57e9, 64e9, 256)  # room-60g's band; unambiguous range 5.5 m
SHEETS = ["glass", "plasterboard", "wood", "concrete", "ceiling_board", "chipboard"]  # (Sionna lacks floorboard there)
SHEET_M = 0.6  # the sheet, metres along +z from the radar
PLATE_M = 1.0  # the plate's front face
HALF_M = 1.0  # both are 2 x 2 m: many Fresnel zones (sqrt(lambda R / 2) = 5 cm) wide
GATE_M = 0.15  # each return's range gate: within this of its surface


def _scene(sheet: tuple[str, float] | None) -> Scene:
    """The plate (metal, 10 cm thick) and optionally a sheet (material, thickness [m]) before it."""
    objects = [{"name": "plate", "material": "metal",
                "shape": {"type": "box", "half_extents_m": [HALF_M, HALF_M, 0.05], "center_m": [0.0, 0.0, PLATE_M + 0.05]}}]
    if sheet is not None:
        objects.append({"name": "sheet", "material": sheet[0],
                        "shape": {"type": "mesh", "builtin": "rectangle", "size_m": 2 * HALF_M,
                                  "center_m": [0.0, 0.0, SHEET_M], "reading": "sheet", "thickness_m": sheet[1]}})
    margin = 0.2
    return Scene(SceneSpec.model_validate({
        "name": "sheet-before-plate",
        "bounds": {"lower_m": [-HALF_M - margin, -HALF_M - margin, SHEET_M - margin],
                   "upper_m": [HALF_M + margin, HALF_M + margin, PLATE_M + 0.1 + margin]},
        "objects": objects}))


def _radar() -> Radar:
    """One Tx and one Rx 1 cm apart at the origin, looking along +z, isotropic, noise-free."""
    return Radar("pair", np.array([[-0.005, 0.0, 0.0]]), np.array([[0.005, 0.0, 0.0]]), FREQUENCIES_HZ,
                 np.eye(3)[None], np.zeros((1, 3)), pattern_exponent=0.0, spreading=True, snr_db=None)


def _profile(h: np.ndarray, centre_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Ranges (R,) [m] within GATE_M of ``centre_m`` on a 10 um grid and the Hann-windowed
    range profile there, sum_f w_f h_f exp(+j 2 k_f r) (R,) complex."""
    ranges = np.arange(centre_m - GATE_M, centre_m + GATE_M, 1e-5)
    k = 2 * np.pi * FREQUENCIES_HZ / SPEED_OF_LIGHT
    return ranges, np.exp(2j * np.outer(ranges, k)) @ (np.hanning(len(k)) * h)


def _peak(h: np.ndarray, centre_m: float) -> tuple[float, float]:
    """(one-way range [m], magnitude) of the strongest return within GATE_M of ``centre_m``."""
    ranges, profile = _profile(h, centre_m)
    return float(ranges[np.abs(profile).argmax()]), float(np.abs(profile).max())


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    """|<a, b>| / (|a| |b|): 1 when the channels agree up to one complex gain."""
    return float(abs(np.vdot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)))


def _conventions(sheet: float, plate: float, thickness_m: float) -> float:
    """The whole channels' correlation the two tools' slab conventions leave, from the two
    returns' gated peaks: the plate's path stands e^{+j k d} further round against the
    sheet's in rfsdf than in Sionna (rfsdf's slab of thickness d centred on the surface, its
    front face d / 2 nearer, T its excess over free space; Sionna's surface with T's whole
    phase less e^{+j q0}), so the correlation is |sum_f (s^2 + p^2 e^{j k_f d})| / (F (s^2 + p^2))."""
    k = 2 * np.pi * FREQUENCIES_HZ / SPEED_OF_LIGHT
    return float(abs(np.sum(sheet**2 + plate**2 * np.exp(1j * k * thickness_m))) / (len(k) * (sheet**2 + plate**2)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sionna-python", required=True, help="a Python interpreter with sionna-rt installed")
    parser.add_argument("--thickness-mm", type=float, default=3.0)
    parser.add_argument("--out", type=Path, default=HERE / "results" / "sionna-slab.json")
    args = parser.parse_args()
    radar, thickness = _radar(), args.thickness_mm * 1e-3
    acquisition = radar.acquisition()
    f_c = float(FREQUENCIES_HZ.mean())

    def channels(sheet, folder: Path) -> dict:
        scene = _scene(sheet)
        clock = time.perf_counter()
        h_rfsdf = simulate(scene, radar, max_samples=4_000_000, transmission=True).data[0, 0, 0].numpy().astype(complex)
        rfsdf_s = time.perf_counter() - clock
        xml, out = export_scene(scene, folder), folder / "sionna.npz"
        clock = time.perf_counter()
        subprocess.run([args.sionna_python, str(HERE / "sionna_paths.py"), str(xml), str(pairs), str(out),
                        "--max-depth", "3", "--refraction"], check=True)
        return {"rfsdf": h_rfsdf, "sionna": np.load(out)["h"][0],
                "time_s": {"rfsdf": round(rfsdf_s, 1), "sionna": round(time.perf_counter() - clock, 1)}}

    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        pairs = Path(tmp) / "pairs.npz"
        np.savez(pairs, tx_m=acquisition.tx_m[0].numpy(), rx_m=acquisition.rx_m[0].numpy(),
                 frequencies_hz=FREQUENCIES_HZ)
        (Path(tmp) / "bare").mkdir()
        bare = channels(None, Path(tmp) / "bare")
        bare_peak = {tool: _peak(bare[tool], PLATE_M) for tool in TOOLS}
        rows["bare plate"] = {"correlation": round(_correlation(bare["rfsdf"], bare["sionna"]), 4),
                              "plate_range_m": {t: round(p[0], 5) for t, p in bare_peak.items()},
                              "time_s": bare["time_s"]}
        print("bare plate", rows["bare plate"], flush=True)
        for name in SHEETS:
            folder = Path(tmp) / name
            folder.mkdir()
            got = channels((name, thickness), folder)
            eps = complex(get_material(name).permittivity(f_c))
            r, t = (complex(c) for c in slab_coefficients(1.0, eps, thickness, f_c, "mean"))
            excess = float(excess_path(1.0, eps.real, thickness))
            delayed = got["sionna"] * np.exp(-2j * np.pi * FREQUENCIES_HZ * 2 * excess / SPEED_OF_LIGHT)
            plate = {tool: _peak(got[tool], PLATE_M) for tool in TOOLS}
            sheet = {tool: _peak(got[tool], SHEET_M) for tool in TOOLS}
            gated = {tool: _profile(got[tool], PLATE_M)[1] for tool in TOOLS}
            rows[name] = {
                "eps": [round(eps.real, 3), round(eps.imag, 3)],
                "plate_over_bare": {tool: round(plate[tool][1] / bare_peak[tool][1], 4) for tool in TOOLS},
                "T_squared": round(abs(t) ** 2, 4),
                "plate_shift_mm": {tool: round((plate[tool][0] - bare_peak[tool][0]) * 1e3, 2) for tool in TOOLS},
                "excess_path_mm": round(excess * 1e3, 2),
                "plate_correlation": round(_correlation(gated["rfsdf"], gated["sionna"]), 4),
                "plate_correlation_sionna_delayed": round(_correlation(gated["rfsdf"], _profile(delayed, PLATE_M)[1]), 4),
                "sheet_over_bare": {tool: round(sheet[tool][1] / bare_peak[tool][1], 4) for tool in TOOLS},
                "R_abs": round(abs(r), 4),
                "sheet_correlation": round(_correlation(_profile(got["rfsdf"], SHEET_M)[1],
                                                        _profile(got["sionna"], SHEET_M)[1]), 4),
                "channel_correlation": round(_correlation(got["rfsdf"], got["sionna"]), 4),
                "channel_correlation_conventions": round(_conventions(sheet["rfsdf"][1], plate["rfsdf"][1], thickness), 4),
                "time_s": got["time_s"]}
            print(name, rows[name], flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"frequencies_ghz": [57.0, 64.0, len(FREQUENCIES_HZ)],
                                    "thickness_mm": args.thickness_mm, "rows": rows}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
