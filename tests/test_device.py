"""--device auto|cpu|cuda: resolved in one place, refused in one line where it cannot run, and
on a machine with a GPU every stage on CUDA agrees with the CPU (skipped, saying why, elsewhere)."""

import dataclasses
import json

import numpy as np
import pytest
import tomli_w
import torch
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.device import resolve_device
from rfsdf.errors import RfsdfError
from rfsdf.geometry import Grid
from rfsdf.mesh import evaluate_on_grid
from rfsdf.radar import load_radar, matched_filter, read_measurements, simulate
from rfsdf.radar.clean import clean_image
from rfsdf.radar.imaging import FAST_MIN_FREQUENCIES, imaging_method
from rfsdf.scene import load_scene

CUDA = torch.cuda.is_available()
needs_cuda = pytest.mark.skipif(not CUDA, reason="no CUDA GPU on this machine (CI has none)")
without_cuda = pytest.mark.skipif(CUDA, reason="this machine has a CUDA GPU: asking for one is not an error here")
WALLS = {"name": "walls", "bounds": {"lower_m": [-1.6, -1.6, 0.8], "upper_m": [1.6, 1.6, 2.2]},
         "objects": [{"name": "east", "material": "concrete",
                      "shape": {"type": "box", "half_extents_m": [0.01, 0.15, 0.15], "center_m": [1.2, 0.0, 1.5]}},
                     {"name": "south", "material": "metal",
                      "shape": {"type": "box", "half_extents_m": [0.15, 0.01, 0.15], "center_m": [0.0, -0.9, 1.5]}}]}


def test_devices_resolve_and_bad_names_are_one_line():
    assert resolve_device("cpu") == torch.device("cpu")
    assert resolve_device("auto").type == ("cuda" if CUDA else "cpu") == resolve_device(None).type
    for bad, reason in (("tpu", "unknown device 'tpu'"), ("cuda:x", "unknown device"), ("mps", "not supported"),
                        ("meta", "not supported")):
        with pytest.raises(RfsdfError, match=f"^train.device: .*{reason}"):
            resolve_device(bad, "train.device")


@without_cuda
def test_cuda_without_a_gpu_is_refused_before_anything_is_written(tmp_path, tiny_files):
    runner = CliRunner()
    data, out = str(tiny_files / "data.h5"), tmp_path / "out"
    out.mkdir()
    commands = {"demo": ["demo", "--quick", "--out", str(out / "demo")],
                "room demo": ["demo", "--model", "primitive", "--quick", "--out", str(out / "room")],
                "simulate": ["simulate", "sphere", "--out", str(out / "s.h5")],
                "dataset": ["simulate", "--random", "2", "--out", str(out / "set")],
                "image": ["image", data, "--out", str(out / "i.h5")],
                "reconstruct": ["reconstruct", data, "--out", str(out / "run"),
                                "--config", str(tiny_files / "tiny.toml")]}
    for name, args in commands.items():
        result = runner.invoke(main, [*args, "--device", "cuda"])
        assert result.exit_code == 2, (name, result.output)
        assert result.output.count("\n") == 1 and "torch sees no CUDA GPU here" in result.output, name
    assert not list(out.iterdir())


def test_imaging_auto_is_fast_only_on_the_cpu(tiny_radar):
    acquisition = tiny_radar.acquisition()
    many = dataclasses.replace(acquisition, frequencies_hz=torch.linspace(77e9, 81e9, FAST_MIN_FREQUENCIES,
                                                                          dtype=torch.float64))
    assert imaging_method(many, "auto") == imaging_method(many, "auto", "cpu") == "fast"
    assert imaging_method(many, "auto", torch.device("cuda")) == "exact"  # a device object needs no GPU
    assert imaging_method(many, "fast", "cuda") == "fast"


@needs_cuda
def test_every_stage_on_cuda_agrees_with_the_cpu(tiny_radar, tiny_files):
    scene = load_scene("sphere")
    on_cpu, on_gpu = (simulate(scene, tiny_radar, seed=0, device=d) for d in ("cpu", "cuda"))
    assert on_gpu.data.device.type == "cpu"  # results come back to the CPU
    assert torch.linalg.norm(on_gpu.data - on_cpu.data) <= 1e-4 * torch.linalg.norm(on_cpu.data)

    data = read_measurements(tiny_files / "data.h5")
    grid = Grid((-0.05,) * 3, (0.05,) * 3, (10, 10, 10))
    images = [matched_filter(data, grid, method="exact", device=d).per_view for d in ("cpu", "cuda")]
    assert torch.linalg.norm(images[1] - images[0]) <= 1e-4 * torch.linalg.norm(images[0])
    cleaned = [clean_image(data, grid, device=d) for d in ("cpu", "cuda")]
    assert all(torch.equal(a, b) for a, b in zip(cleaned[0].component_index, cleaned[1].component_index))

    sdf = scene.sdf
    values = [evaluate_on_grid(sdf, grid, device=d) for d in ("cpu", "cuda")]
    np.testing.assert_allclose(values[1], values[0], atol=1e-6)


@needs_cuda
def test_a_room_simulated_by_facets_on_cuda_agrees_with_the_cpu_and_its_demo_runs_there(tmp_path):
    """The facet path (two 30 cm walls a metre from room-60g's views) on CUDA against the CPU, and `demo --model
    primitive --device cuda` end to end (its simulation on the GPU)."""
    scene_file = tmp_path / "walls.toml"
    scene_file.write_text(tomli_w.dumps(WALLS))
    scene, radar = load_scene(str(scene_file)), load_radar("room-60g")
    on_cpu, on_gpu = (simulate(scene, radar, seed=0, max_samples=40_000, device=d) for d in ("cpu", "cuda"))
    assert "surface facets in view" in on_cpu.metadata["surface_sampling"]
    assert torch.linalg.norm(on_gpu.data - on_cpu.data) <= 1e-4 * torch.linalg.norm(on_cpu.data)
    result = CliRunner().invoke(main, ["--quiet", "demo", "--scene", str(scene_file), "--radar", "room-60g",
                                       "--model", "primitive", "--quick", "--device", "cuda",
                                       "--out", str(tmp_path / "d")])
    assert result.exit_code == 0, result.output
    assert "primitive" in json.loads((tmp_path / "d" / "metrics.json").read_text())["models"]


@needs_cuda
def test_the_quick_demo_runs_on_cuda(tmp_path):
    result = CliRunner().invoke(main, ["--quiet", "demo", "--quick", "--out", str(tmp_path / "d"), "--device", "cuda"])
    assert result.exit_code == 0, result.output
    assert "(cuda)" in result.output and (tmp_path / "d" / "metrics.json").exists()
