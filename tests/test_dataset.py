"""Random scenes (reproducible, valid, no overlaps, inside the bounds) and simulated datasets."""

import json

import pytest
import torch
from click.testing import CliRunner

from rfsdf.cli import main

from rfsdf.geometry import Grid
from rfsdf.random_scenes import MATERIALS, SHAPE_KINDS, random_scene_spec
from rfsdf.scene import Scene
from rfsdf.scene_spec import SceneSpec


def test_random_scenes_are_reproducible_valid_and_their_objects_apart_and_inside():
    assert random_scene_spec(3) == random_scene_spec(3) and random_scene_spec(3) != random_scene_spec(4)
    kinds, materials = set(), set()
    grid = Grid((-0.15,) * 3, (0.15,) * 3, (60, 60, 60))  # 5 mm voxels; objects are >= 10 mm apart
    points = grid.points()
    on_faces = (points.abs() >= 0.15 - 0.0026).any(dim=1)
    for seed in range(12):
        spec = random_scene_spec(seed)
        scene = Scene(SceneSpec.model_validate(spec))
        assert 2 <= len(scene.objects) <= 5
        inside = torch.stack([obj.sdf(points) <= 0 for obj in scene.objects])
        assert int(inside.sum(0).max()) <= 1  # no voxel inside two objects
        assert not bool(inside[:, on_faces].any())  # nothing touches the bounds
        assert all(int(mask.sum()) > 0 for mask in inside)  # every object occupies some voxels
        kinds |= {o["shape"]["type"] for o in spec["objects"]}
        materials |= {o["material"] for o in spec["objects"]}
    assert kinds == set(SHAPE_KINDS) and materials == set(MATERIALS)


def test_dataset_writes_scene_files_and_measurements_and_a_rerun_reuses_them(tmp_path):
    out = tmp_path / "data"
    args = ["--quiet", "simulate", "--random", "2", "--seed", "5", "--out", str(out)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    index = json.loads((out / "dataset.json").read_text())
    assert [row["name"] for row in index["scenes"]] == ["scene-00000", "scene-00001"]
    assert [row["seed"] for row in index["scenes"]] == [5, 6] and {r["status"] for r in index["scenes"]} == {"done"}
    from rfsdf.radar import read_measurements
    from rfsdf.scene import load_scene

    scene = load_scene(out / "scene-00001.toml")
    assert len(scene.objects) == index["scenes"][1]["objects"]
    assert read_measurements(out / "scene-00001.h5").data.abs().max() > 0
    rerun = CliRunner().invoke(main, args)
    assert rerun.exit_code == 0 and "scene-00000: reused" in rerun.output


@pytest.mark.parametrize("args", [["objects", "--random", "2"], []])
def test_simulate_needs_a_scene_or_random_not_both(tmp_path, args):
    result = CliRunner().invoke(main, ["simulate", *args, "--out", str(tmp_path / "x")])
    assert result.exit_code == 2 and result.output.strip() == "error: give a SCENE_NAME or --random N (not both)"
    assert not (tmp_path / "x").exists()


def test_a_random_dataset_is_simulated_opaque():
    result = CliRunner().invoke(main, ["simulate", "--random", "2", "--transmission", "--out", "x"])
    assert result.exit_code == 2
    assert result.output.strip() == "error: --transmission: random datasets are simulated opaque; give a SCENE_NAME"
