import json

import numpy as np
import torch
import trimesh
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.material_estimates import read_materials
from rfsdf.radar import read_image, read_measurements
from rfsdf.recon import Problem, Trainer, load_recon_config
from rfsdf.recon.checkpoint import CHECKPOINT_NAME, read_checkpoint


def test_reconstruct_mesh_evaluate_and_resume(tmp_path, tiny_files):
    runner = CliRunner()
    args = ["reconstruct", str(tmp_path / "data.h5"), "--image", str(tmp_path / "image.h5"),
            "--out", str(tmp_path / "run"), "--config", str(tmp_path / "tiny.toml")]
    result = runner.invoke(main, args)
    assert result.exit_code == 0, result.output
    for name in ("checkpoint.pt", "log.csv", "config.toml", "mesh.ply"):
        assert (tmp_path / "run" / name).exists()
    again = runner.invoke(main, args)
    assert again.exit_code == 2 and "already holds a run" in again.output
    resumed = runner.invoke(main, args[:-2] + ["--resume"])  # finished run: nothing left, re-meshes
    assert resumed.exit_code == 0, resumed.output

    result = runner.invoke(main, ["mesh", str(tmp_path / "run"), "--out", str(tmp_path / "m.obj"), "--resolution", "20"])
    assert result.exit_code == 0, result.output
    assert len(trimesh.load(tmp_path / "m.obj", force="mesh").faces) > 0

    result = runner.invoke(main, ["evaluate", str(tmp_path / "m.obj"), "--scene", "sphere", "--json"])
    assert result.exit_code == 0, result.output
    metrics = json.loads(result.output)
    assert metrics["chamfer_l1_mm"] > 0 and 0 <= metrics["fscore"] <= 1


def test_materials_of_a_run_folder_read_the_data_as_the_fit_in_hand_does(tmp_path, tiny_files):
    """`rfsdf materials RUN` rebuilds the fit from its checkpoint (config, grid, field) and the
    measurements, and prints the closed-form readout that the same fit, still in hand, reads;
    a checkpoint written before the grid was kept gets the head's readings and a line saying why
    (and that a known gain given after the fit is not applied to them)."""
    runner = CliRunner()
    args = ["reconstruct", str(tmp_path / "data.h5"), "--image", str(tmp_path / "image.h5"),
            "--out", str(tmp_path / "run"), "--config", str(tmp_path / "tiny.toml")]
    assert runner.invoke(main, args).exit_code == 0
    trainer = Trainer(Problem(read_measurements(tmp_path / "data.h5"), read_image(tmp_path / "image.h5").grid,
                              str(tmp_path / "data.h5")), load_recon_config(tmp_path / "tiny.toml"), tmp_path / "run")
    fit = trainer.fit(resume=True)
    in_hand = read_materials(trainer, trimesh.load(tmp_path / "run" / "mesh.ply", force="mesh"))[1].value
    assert fit.field.material_head is not None and len(in_hand) >= 1
    table = runner.invoke(main, ["materials", str(tmp_path / "run")])
    assert table.exit_code == 0, table.output
    rows = [line.split() for line in table.output.splitlines() if line.startswith("  component")]
    assert [row[7] for row in rows] == [f"{value:.2f}" if np.isfinite(value) else "-" for value in in_hand]
    assert "no closed-form readout" not in table.output

    state = read_checkpoint(tmp_path / "run" / CHECKPOINT_NAME, "cpu")
    state["grid"]["upper_m"] = [float("inf")] * 3
    torch.save(state, tmp_path / "run" / CHECKPOINT_NAME)
    refused = runner.invoke(main, ["materials", str(tmp_path / "run")])
    assert refused.exit_code == 2 and refused.output.count("\n") == 1, refused.output
    assert "checkpoint.pt: grid: not a grid rfsdf wrote (its box is not finite)" in refused.output
    del state["grid"]
    torch.save(state, tmp_path / "run" / CHECKPOINT_NAME)
    table = runner.invoke(main, ["materials", str(tmp_path / "run")])
    assert table.exit_code == 0, table.output
    assert table.output.rstrip().endswith("(no closed-form readout: the run's checkpoint keeps no grid "
                                          "(written before rfsdf kept one))")
    state["config"]["calibration"]["gain"] = 2.5  # a capture's gain, given after the relative fit
    torch.save(state, tmp_path / "run" / CHECKPOINT_NAME)
    table = runner.invoke(main, ["materials", str(tmp_path / "run")])
    assert table.output.rstrip().endswith("; the head's reflectivities stay relative, not in the known gain 2.5)")


def test_reconstruct_and_image_need_no_scene(tmp_path, tiny_files):
    """Real data have no scene: the box comes from --bounds (or bounds stored in the file)."""
    runner = CliRunner()
    bounds = "-0.05,-0.05,-0.05,0.05,0.05,0.05"
    result = runner.invoke(main, ["image", str(tmp_path / "data.h5"), "--out", str(tmp_path / "i.h5"),
                                  "--bounds", bounds, "--voxel", "0.01"])
    assert result.exit_code == 0, result.output
    assert "(10, 10, 10) voxels" in result.output
    result = runner.invoke(main, ["reconstruct", str(tmp_path / "data.h5"), "--out", str(tmp_path / "run"),
                                  "--bounds", bounds, "--voxel", "0.01", "--config", str(tmp_path / "tiny.toml")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "run" / "mesh.ply").exists()
    result = runner.invoke(main, ["image", str(tmp_path / "data.h5"), "--out", str(tmp_path / "j.h5")])
    assert result.exit_code == 2 and "pass --bounds" in result.output
    for bad in ("1,2,3", "0,0,0,-1,1,1", "a,b,c,d,e,f", "0,0,0,nan,1,1"):
        result = runner.invoke(main, ["image", str(tmp_path / "data.h5"), "--out", str(tmp_path / "k.h5"), "--bounds", bad])
        assert result.exit_code == 2 and result.output.startswith("error: --bounds") and "Traceback" not in result.output
        assert not (tmp_path / "k.h5").exists()


def test_bad_inputs_get_one_line(tmp_path, tiny_files):
    runner = CliRunner()
    result = runner.invoke(main, ["mesh", str(tmp_path), "--out", str(tmp_path / "m.ply")])
    assert result.exit_code == 2 and "no checkpoint.pt" in result.output and "Traceback" not in result.output
    result = runner.invoke(main, ["evaluate", str(tmp_path / "none.ply"), "--scene", "sphere"])
    assert result.exit_code == 2 and "file not found" in result.output
    (tmp_path / "bad.toml").write_text("[train]\nsteps = -3\n")
    result = runner.invoke(main, ["reconstruct", str(tmp_path / "data.h5"), "--image", str(tmp_path / "image.h5"),
                                  "--out", str(tmp_path / "r"), "--config", str(tmp_path / "bad.toml")])
    assert result.exit_code == 2 and "train.steps" in result.output


class _Payload:
    """Unpickling this object calls open(path, 'w'): it would create a file."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return (open, (self.path, "w"))


def test_a_crafted_checkpoint_runs_no_code(tmp_path, tiny_files):
    run = tmp_path / "run"
    run.mkdir()
    marker = tmp_path / "pwned"
    torch.save({"step": 0, "field": _Payload(marker)}, run / "checkpoint.pt")
    runner = CliRunner()
    for args in (["mesh", str(run), "--out", str(tmp_path / "m.ply")],
                 ["reconstruct", str(tmp_path / "data.h5"), "--image", str(tmp_path / "image.h5"),
                  "--out", str(run), "--config", str(tmp_path / "tiny.toml"), "--resume"]):
        result = runner.invoke(main, args)
        assert result.exit_code == 2, result.output
        assert result.output.startswith("error: ") and result.output.count("\n") == 1, result.output
        assert "not a readable rfsdf checkpoint" in result.output
        assert not marker.exists()
    assert not (tmp_path / "m.ply").exists()


def test_reconstruct_through_a_known_box_less_its_empty_capture(tmp_path, tiny_files):
    """Objects in a known box: --background (the empty box's measurements, same acquisition)
    is subtracted from the data, and --through (the box's scene) puts its walls on every
    line of sight; a background of another acquisition is refused in one line naming it."""
    from rfsdf.radar import read_measurements, write_measurements
    from rfsdf.radar.acquisition import Measurements
    from rfsdf.radar.operator import SensingOperator

    data = read_measurements(tmp_path / "data.h5")
    wall = SensingOperator(data.acquisition).forward(torch.tensor([[-0.03, 0.02, 0.0]]),
                                                     torch.ones(1, dtype=torch.complex64))
    write_measurements(tmp_path / "empty.h5", Measurements(data.acquisition, wall))
    write_measurements(tmp_path / "boxed.h5", Measurements(data.acquisition, data.data + wall))
    assert torch.allclose(read_measurements(tmp_path / "boxed.h5").less(read_measurements(tmp_path / "empty.h5")).data,
                          data.data, atol=1e-6)
    (tmp_path / "box.toml").write_text(
        'name = "box"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\nupper_m = [0.1, 0.1, 0.1]\n'
        '[[objects]]\nname = "box"\nmaterial = "wood"\n[objects.shape]\ntype = "difference"\nchildren = [\n'
        '  { type = "box", half_extents_m = [0.08, 0.08, 0.08], center_m = [0.0, 0.0, 0.0] },\n'
        '  { type = "box", half_extents_m = [0.077, 0.077, 0.077], center_m = [0.0, 0.0, 0.0] },\n]\n')
    runner = CliRunner()
    args = ["reconstruct", str(tmp_path / "boxed.h5"), "--image", str(tmp_path / "image.h5"),
            "--config", str(tmp_path / "tiny.toml"), "--through", str(tmp_path / "box.toml")]
    result = runner.invoke(main, [*args, "--background", str(tmp_path / "empty.h5"), "--out", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "run" / "mesh.ply").exists()

    other = Measurements(data.acquisition.every_frequency(2), wall[..., ::2])
    write_measurements(tmp_path / "other.h5", other)
    result = runner.invoke(main, [*args, "--background", str(tmp_path / "other.h5"), "--out", str(tmp_path / "bad")])
    assert result.exit_code == 2, result.output
    assert result.output.strip() == (f"error: {tmp_path / 'other.h5'}: frequencies_hz: differs from the data's "
                                     "(a background must share their acquisition)")
    assert not (tmp_path / "bad").exists()
    result = runner.invoke(main, [*args[:-2], "--model", "primitive", "--scene", "sphere", "--through", "sphere",
                                  "--out", str(tmp_path / "prim")])
    assert result.exit_code == 2 and "--through" in result.output and "Traceback" not in result.output
