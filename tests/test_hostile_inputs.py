"""Hostile input: one 'error:' line, exit code 2, and no file created or changed."""

import copy
import hashlib
import json
import os
import re
from importlib import resources
from pathlib import Path

import h5py
import pytest
import tomli_w
import torch
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rfsdf.cli import main
from rfsdf.config import MAX_TOML_DEPTH, read_toml
from rfsdf.errors import RfsdfError
from rfsdf.jsonio import to_json
from rfsdf.mesh import extract_mesh
from rfsdf.radar import load_radar
from rfsdf.recon import ReconConfig, load_recon_config
from rfsdf.scene import load_scene
from rfsdf.sweep import load_sweep


def _snapshot(folder) -> dict:
    """Every file under ``folder`` and a digest of its bytes."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(args, folder, *, cwd=None) -> str:
    """Run the CLI; assert one error line, exit 2 and nothing written under ``folder``."""
    before = _snapshot(folder)
    old = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        result = CliRunner().invoke(main, [str(a) for a in args])
    finally:
        os.chdir(old)
    assert result.exit_code == 2, result.output
    assert result.output.startswith("error: ") and result.output.count("\n") == 1, result.output
    assert _snapshot(folder) == before
    return result.output


def test_a_scene_name_cannot_escape_the_output_folder(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    (work / "s.toml").write_text(
        'name = "../escaped"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\nupper_m = [0.1, 0.1, 0.1]\n'
        '[[objects]]\nname = "ball"\nmaterial = "metal"\nshape = { type = "sphere", radius_m = 0.02 }\n')
    line = _refused(["scene", "show", "s.toml"], tmp_path, cwd=work)
    assert "s.toml: name:" in line and "plain name" in line


@pytest.mark.parametrize("case", ["image", "simulate", "import", "reconstruct", "mesh"])
def test_an_output_that_is_an_input_is_refused(tmp_path, tiny_files, case):
    scene = tmp_path / "scene.toml"
    scene.write_text(
        'name = "ball"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\nupper_m = [0.1, 0.1, 0.1]\n'
        '[[objects]]\nname = "ball"\nmaterial = "metal"\nshape = { type = "sphere", radius_m = 0.02 }\n')
    run = tmp_path / "run"
    run.mkdir()
    (run / "checkpoint.pt").write_bytes(b"not a checkpoint")
    data = tmp_path / "data.h5"
    args = {"image": ["image", data, "--out", data, "--bounds", "-0.05,-0.05,-0.05,0.05,0.05,0.05"],
            "simulate": ["simulate", scene, "--out", scene],
            "import": ["import-fmcw", data, "--out", data],
            "reconstruct": ["reconstruct", data, "--out", tmp_path / "tiny.toml", "--config", tmp_path / "tiny.toml"],
            "mesh": ["mesh", run, "--out", run / "checkpoint.pt"]}[case]
    assert "would destroy the input" in _refused(args, tmp_path)


# Property-based: any hostile value of any numeric setting --------------------------------
HOSTILE_NUMBERS = st.one_of(
    st.sampled_from([float("nan"), float("inf"), float("-inf"), 0.0, -1.0, 1e300, -1e300, 1e-300]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.sampled_from(["text", "", [], {}, True, [1.0, 2.0]]),
)


def _numeric_leaves(table, path=()):
    """Paths of every number (and number inside a list) in a parsed TOML table."""
    if isinstance(table, dict):
        for key, value in table.items():
            yield from _numeric_leaves(value, (*path, key))
    elif isinstance(table, list):
        for index, value in enumerate(table):
            yield from _numeric_leaves(value, (*path, index))
    elif isinstance(table, (int, float)) and not isinstance(table, bool):
        yield path


def _replaced(table, path, value):
    table = copy.deepcopy(table)
    node = table
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return table


def _loads_or_refuses(load, table, tmp_path):
    """``load`` of ``table`` written as TOML either works or raises one RfsdfError naming the file."""
    path = tmp_path / "case.toml"
    try:
        path.write_text(tomli_w.dumps(table))
    except (TypeError, ValueError):  # not representable in TOML (e.g. NaN inside a list): nothing to test
        return
    try:
        load(path)
    except RfsdfError as exc:
        assert str(exc).startswith(str(path)) and "\n" not in str(exc), exc


def _preset_table(package, name):
    return read_toml(resources.files(package) / f"{name}.toml")


@pytest.mark.parametrize("package, name, load", [
    ("rfsdf.presets.scenes", "objects", load_scene),
    ("rfsdf.presets.radars", "near-77g", load_radar),
])
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_hostile_number_in_a_scene_or_radar_file_is_one_error(tmp_path, package, name, load, data):
    table = _preset_table(package, name)
    path = data.draw(st.sampled_from(sorted(_numeric_leaves(table), key=str)))
    _loads_or_refuses(load, _replaced(table, path, data.draw(HOSTILE_NUMBERS)), tmp_path)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_hostile_number_in_a_reconstruction_config_is_one_error(tmp_path, data):
    table = ReconConfig().model_dump(exclude_none=True)
    path = data.draw(st.sampled_from(sorted(_numeric_leaves(table), key=str)))
    _loads_or_refuses(load_recon_config, _replaced(table, path, data.draw(HOSTILE_NUMBERS)), tmp_path)


_NUMERIC_OPTIONS = [  # command lines; OPTION takes the bad value, which every one of them must refuse
    ["image", "data.h5", "--out", "i.h5", "--voxel", "OPTION"],
    ["reconstruct", "data.h5", "--out", "run", "--voxel", "OPTION"],
    ["evaluate", "m.ply", "--scene", "sphere", "--threshold", "OPTION"],
    ["mesh", "run", "--out", "m.ply", "--resolution", "OPTION"],
    ["simulate", "sphere", "--out", "s.h5", "--seed", "OPTION"],
]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(args=st.sampled_from(_NUMERIC_OPTIONS),
       value=st.one_of(st.sampled_from(["nan", "inf", "-inf", "0.0", "-1", "1e999", "abc", "", "0x10", "1e100000"]),
                       st.floats(max_value=0).map(repr), st.integers(max_value=-1).map(str)))
def test_a_bad_numeric_option_is_one_line_before_any_work(tmp_path, args, value):
    _refused([value if a == "OPTION" else tmp_path / a if a.endswith((".h5", ".ply")) or a == "run" else a
              for a in args], tmp_path)


def test_every_command_refuses_an_object_outside_the_bounds(tmp_path):
    """One validation serves all: scene show drew a blank picture of what simulate refused."""
    (tmp_path / "far.toml").write_text(
        'name = "far"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\nupper_m = [0.1, 0.1, 0.1]\n'
        '[[objects]]\nname = "ball"\nmaterial = "metal"\n'
        'shape = { type = "sphere", radius_m = 0.02, transform = { translate_m = [5.0, 0.0, 0.0] } }\n')
    for args in (["scene", "show", tmp_path / "far.toml", "--out", tmp_path / "far.png"],
                 ["simulate", tmp_path / "far.toml", "--out", tmp_path / "far.h5"]):
        assert "object 'ball' lies outside the bounds" in _refused(args, tmp_path)


def test_json_output_is_strict_json():
    text = to_json({"a": float("nan"), "b": [1.0, float("inf")], "c": {"d": -float("inf"), "e": 2}})
    assert json.loads(text) == {"a": None, "b": [1.0, None], "c": {"d": None, "e": 2}}
    assert "NaN" not in text and "Infinity" not in text


@pytest.mark.parametrize("kind", ["fifo", "device", "folder"])
def test_a_non_regular_input_file_is_one_line_at_once(tmp_path, tiny_files, kind):
    """A FIFO would block a reader forever and /dev/zero never end: refused before reading."""
    special = {"fifo": tmp_path / "pipe.toml", "device": "/dev/zero", "folder": tmp_path / "folder.toml"}[kind]
    if kind == "fifo":
        os.mkfifo(special)
    elif kind == "folder":
        special.mkdir()
    for args in (["scene", "show", special, "--out", tmp_path / "s.png"],
                 ["image", special, "--out", tmp_path / "i.h5", "--bounds", "-0.05,-0.05,-0.05,0.05,0.05,0.05"],
                 ["reconstruct", tmp_path / "data.h5", "--out", tmp_path / "run", "--config", special],
                 ["evaluate", special, "--scene", "sphere"]):
        line = _refused(args, tmp_path)
        assert str(special) in line and ("not a regular file" in line or "is a folder" in line), line


def test_sizes_are_checked_before_allocating(tmp_path, tiny_files):
    """An image, a mesh or an HDF5 dataset that cannot fit is one line, not a MemoryError."""
    bounds = "-0.05,-0.05,-0.05,0.05,0.05,0.05"
    line = _refused(["image", tmp_path / "data.h5", "--out", tmp_path / "i.h5", "--bounds", bounds, "--voxel", "1e-5"],
                    tmp_path)
    assert "the image (4 views x (10000, 10000, 10000) voxels" in line and "GiB of memory available" in line
    line = _refused(["reconstruct", tmp_path / "data.h5", "--out", tmp_path / "run", "--bounds", bounds,
                     "--voxel", "1e-5", "--config", tmp_path / "tiny.toml"], tmp_path)
    assert "the fit's images" in line
    with h5py.File(tmp_path / "huge.h5", "w") as fh:  # a small file that declares 2^60 samples
        fh.attrs.update({"format": "rfsdf.measurements", "format_version": 1})
        fh.create_dataset("tx_m", shape=(2**30, 2**30), dtype="f8")
    before = (tmp_path / "huge.h5").stat().st_size
    line = _refused(["image", tmp_path / "huge.h5", "--out", tmp_path / "i.h5", "--bounds", bounds], tmp_path)
    assert "huge.h5: tx_m: its declared shape (1073741824, 1073741824)" in line and before < 10_000


def test_marching_cubes_is_sized_first():
    with pytest.raises(RfsdfError, match=r"marching cubes on \(100000, 100000, 100000\) voxels"):
        extract_mesh(lambda p: p.norm(dim=1) - 0.5, (-1, -1, -1), (1, 1, 1), 100_000)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(["measurements", "image", "checkpoint"]), cut=st.floats(0, 0.9), noise=st.binary(max_size=512))
def test_random_and_truncated_files_are_one_line(tmp_path, tiny_files, kind, cut, noise):
    """A real file cut anywhere (then junk, or nothing), or pure junk: one line, no traceback."""
    run = tmp_path / "run"
    run.mkdir(exist_ok=True)
    if not (run / "checkpoint.pt").exists():
        torch.save({"step": 0, "field": {"w": torch.zeros(3)}}, run / "checkpoint.pt")
    source = {"measurements": tmp_path / "data.h5", "image": tmp_path / "image.h5", "checkpoint": run / "checkpoint.pt"}
    good = source[kind].read_bytes()
    bad = tmp_path / f"bad-{kind}"
    bad.mkdir(exist_ok=True)
    target = bad / ("checkpoint.pt" if kind == "checkpoint" else "file.h5")
    target.write_bytes(good[: int(cut * len(good))] + noise)
    args = {"measurements": ["image", target, "--out", tmp_path / "o.h5", "--bounds", "-0.05,-0.05,-0.05,0.05,0.05,0.05"],
            "image": ["reconstruct", tmp_path / "data.h5", "--image", target, "--out", tmp_path / "r"],
            "checkpoint": ["mesh", bad, "--out", tmp_path / "m.ply"]}[kind]
    _refused(args, tmp_path)


def test_a_material_outside_the_radar_band_is_refused_before_any_work(tmp_path):
    """ITU-R brick has no model above 40 GHz: one line before anything is simulated or written."""
    (tmp_path / "brick.toml").write_text(
        'name = "bricks"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\nupper_m = [0.1, 0.1, 0.1]\n'
        '[[objects]]\nname = "wall"\nmaterial = "brick"\nshape = { type = "box", half_extents_m = [0.03, 0.03, 0.01] }\n')
    for args in (["demo", "--quick", "--scene", tmp_path / "brick.toml", "--out", tmp_path / "d"],
                 ["simulate", tmp_path / "brick.toml", "--out", tmp_path / "s.h5"]):
        line = _refused(args, tmp_path)
        assert "brick.toml: object 'wall': material 'brick'" in line and "range 1-40, 110-330 GHz" in line, line
    assert not (tmp_path / "d").exists()


# Batch work: every file kind through the one reader, sweeps and random datasets ----------
_READERS = {"scene": load_scene, "radar": load_radar, "recon": load_recon_config, "sweep": load_sweep}


@pytest.mark.parametrize("kind", sorted(_READERS))
@pytest.mark.parametrize("depth", [MAX_TOML_DEPTH + 1, 300, 100_000])
def test_a_toml_file_nested_too_deep_is_one_error_for_every_kind_of_file(tmp_path, kind, depth):
    """Arrays nested past MAX_TOML_DEPTH: one line from read_toml whether tomllib parses them
    (300 levels; later readers would recurse) or itself runs out of stack (100,000)."""
    path = tmp_path / f"{kind}.toml"
    path.write_text("x = " + "[" * depth + "]" * depth + "\n")
    with pytest.raises(RfsdfError, match=re.escape(f"{path}: invalid TOML: tables and arrays nest deeper than "
                                                   f"{MAX_TOML_DEPTH} levels")):
        _READERS[kind](path)


def test_a_toml_file_nested_too_deep_is_one_line_from_every_command(tmp_path):
    deep = tmp_path / "deep.toml"
    deep.write_text("x = " + "[" * 20_000 + "]" * 20_000 + "\n")
    for args in (["scene", "show", deep, "--out", tmp_path / "s.png"], ["sweep", deep, "--out", tmp_path / "o"],
                 ["simulate", "sphere", "--radar", deep, "--out", tmp_path / "s.h5"],
                 ["reconstruct", tmp_path / "d.h5", "--out", tmp_path / "r", "--config", deep]):
        assert "nest deeper than" in _refused(args, tmp_path)


def test_the_deepest_real_file_is_far_from_the_limit():
    """The limit refuses nothing real: every preset and example is at most a few levels deep."""
    from rfsdf.config import _nesting_depth

    files = [*resources.files("rfsdf.presets.scenes").iterdir(), *resources.files("rfsdf.presets.radars").iterdir(),
             *Path(__file__).parents[1].glob("examples/**/*.toml"), *Path(__file__).parents[1].glob("benchmarks/**/*.toml")]
    depths = [_nesting_depth(read_toml(f)) for f in files if str(f).endswith(".toml")]
    assert len(depths) > 10 and max(depths) <= MAX_TOML_DEPTH // 4, max(depths)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_hostile_number_in_a_sweep_file_is_one_error(tmp_path, data):
    table = {"defaults": {"quick": True, "voxel_m": 0.015, "recon": {"train": {"steps": 6, "lr": 1e-3}}},
             "grid": {"seed": [0, 1]}, "jobs": [{"scene": "sphere", "recon": {"init": {"threshold": 0.1}}}]}
    path = data.draw(st.sampled_from(sorted(_numeric_leaves(table), key=str)))
    _loads_or_refuses(load_sweep, _replaced(table, path, data.draw(HOSTILE_NUMBERS)), tmp_path)


_DATASET_RANGES = {"--random": (1, 10**6), "--seed": (0, 2**32 - 1), "--workers": (1, 1024)}


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(option=st.sampled_from(sorted(_DATASET_RANGES)),
       value=st.one_of(st.sampled_from(["nan", "inf", "-1", "0", "1e999", "abc", "", "2.5", "0x10"]),
                       st.integers(max_value=0).map(str), st.integers(min_value=1024).map(str)))
def test_a_bad_random_dataset_option_is_one_line_before_any_work(tmp_path, option, value):
    low, high = _DATASET_RANGES[option]
    if value.lstrip("-").isdigit() and low <= int(value) <= high:
        return  # a valid value: nothing to refuse
    args = {"--random": "2", "--seed": "0", "--workers": "1", option: value}
    _refused(["simulate", "--out", tmp_path / "ds", *(x for kv in args.items() for x in kv)], tmp_path)


def test_a_random_dataset_that_cannot_be_made_is_refused_before_any_scene(tmp_path):
    line = _refused(["simulate", "--random", "2", "--radar", "no-such-radar", "--out", tmp_path / "ds"], tmp_path)
    assert "no-such-radar: no such radar file or preset" in line
    line = _refused(["simulate", "--random", "1000000", "--radar", "dense-77g", "--out", tmp_path / "ds"], tmp_path)
    assert re.search(r"ds: 1,000,000 scenes of about [\d.]+ MiB each, [\d.e+]+ GiB in all, more than the", line), line
    assert not (tmp_path / "ds").exists()


def test_a_report_names_the_field_of_metrics_json_that_is_wrong(tmp_path):
    (tmp_path / "demo-settings.json").write_text(json.dumps({"scene": "objects", "radar": "near-77g"}))
    method = {"label": "x", "full": {"chamfer_l1_mm": 3.0}, "objects": {"ball": {"recall": 1.0}}}
    methods = {name: copy.deepcopy(method) for name in ("neural", "mf_threshold", "clean_threshold", "clean_detection")}
    methods["clean_threshold"]["full"]["chamfer_l1_mm"] = "3.1 mm"
    (tmp_path / "metrics.json").write_text(json.dumps({"methods": methods}))
    line = _refused(["report", tmp_path], tmp_path)
    assert "metrics.json: methods.clean_threshold.full.chamfer_l1_mm: Input should be a valid number" in line, line
    del methods["clean_threshold"], methods["mf_threshold"]  # every demo has the latter (the CLEAN ones only
    # with a CLEAN warm start)
    (tmp_path / "metrics.json").write_text(json.dumps({"methods": methods}))
    assert "metrics.json: methods: missing method(s) mf_threshold" in _refused(["report", tmp_path], tmp_path)


def test_material_inputs_are_one_line(tmp_path, tiny_files):
    """An unknown class, a class twice, `materials` on a folder that is no run or whose fit had
    no head: one error line naming the file and field, nothing written."""
    for classes, reason in ((['"metal"', '"unobtainium"'], "unknown material 'unobtainium'"),
                            (['"metal"', '"pec"'], "each material class once")):
        config = tmp_path / "materials.toml"
        config.write_text(f"[field]\nmaterials = [{', '.join(classes)}]\n")
        line = _refused(["reconstruct", tmp_path / "data.h5", "--out", tmp_path / "run", "--config", config], tmp_path)
        assert f"{config}: field.materials: " in line and reason in line, line
    assert "no checkpoint.pt" in _refused(["materials", tmp_path], tmp_path)
    demo = tmp_path / "demo"
    demo.mkdir()
    (demo / "metrics.json").write_text(json.dumps({"methods": {}, "materials": None}))
    assert "metrics.json: materials: the fit had no material head" in _refused(["materials", demo], tmp_path)
    estimate = {"name": "ball", "predicted": "metal", "probabilities": {"metal": 1.0}, "eps_real": None,
                "eps_real_interval": None, "observed_fraction": "lots"}
    (demo / "metrics.json").write_text(json.dumps({"materials": {
        "objects": [estimate], "components": [], "accuracy": None, "min_observed_fraction": 0.15, "calibration": ""}}))
    line = _refused(["materials", demo], tmp_path)
    assert "metrics.json: materials: objects[0].observed_fraction: Input should be a valid number" in line, line


def test_a_calibration_reference_is_checked_before_any_work(tmp_path, tiny_files):
    """A reference that is not NAME=MATERIAL, whose material is no class of the head, with no
    scene to place it, naming no object of the scene, or an object no view observes: one
    error line naming the file or option and the field, exit 2, nothing written."""
    data, run = tmp_path / "data.h5", tmp_path / "run"
    config = tmp_path / "cal.toml"
    config.write_text('[calibration]\nreference = "ball"\n')
    line = _refused(["reconstruct", data, "--out", run, "--config", config], tmp_path)
    assert f"{config}: calibration.reference: expected NAME=MATERIAL" in line, line
    line = _refused(["reconstruct", data, "--out", run, "--reference", "ball=wood", "--config", config], tmp_path)
    assert "calibration.reference: expected NAME=MATERIAL" in line, line  # the file is read first
    config.write_text('[field]\nmaterials = ["glass", "wood"]\n')
    line = _refused(["reconstruct", data, "--out", run, "--config", config, "--reference", "ball=metal"], tmp_path)
    assert "--reference" in line and "calibration.reference: 'metal' is not one of field.materials" in line, line
    line = _refused(["reconstruct", data, "--out", run, "--reference", "ball=metal"], tmp_path)
    assert "needs --scene" in line, line
    scene = tmp_path / "s.toml"
    scene.write_text(
        'name = "hidden"\n[bounds]\nlower_m = [-0.05, -0.05, -0.05]\nupper_m = [0.05, 0.05, 0.05]\n'
        '[[objects]]\nname = "shell"\nmaterial = "wood"\nshape = { type = "sphere", radius_m = 0.03 }\n'
        '[[objects]]\nname = "core"\nmaterial = "metal"\nshape = { type = "sphere", radius_m = 0.01 }\n')
    line = _refused(["reconstruct", data, "--out", run, "--reference", "ball=metal", "--scene", scene], tmp_path)
    assert "calibration.reference ball=metal: scene 'hidden' has no object 'ball' (it has shell, core)" in line, line
    line = _refused(["reconstruct", data, "--out", run, "--reference", "core=metal", "--scene", scene], tmp_path)
    assert "object 'core' is observed by no view" in line, line  # inside the wooden shell
    line = _refused(["demo", "--quick", "--out", run, "--no-materials", "--reference", "metal_ball=metal"], tmp_path)
    assert "calibration.reference: 'metal' is not one of field.materials []" in line, line
    line = _refused(["demo", "--quick", "--out", run, "--relative", "--reference", "metal_ball=metal"], tmp_path)
    assert "--relative and --reference exclude each other" in line, line
    declared = tmp_path / "declared.toml"
    declared.write_text(scene.read_text().replace('name = "hidden"\n', 'name = "hidden"\ncalibration_reference = "ball"\n'))
    line = _refused(["demo", "--quick", "--out", run, "--scene", declared], tmp_path)
    assert f"{declared}: calibration_reference: no object 'ball' (the objects are shell, core)" in line, line


def test_a_scene_model_is_checked_before_any_work(tmp_path, tiny_files):
    """A parameter table with no start, a start outside its bounds, a free parameter on a
    shape that has no such parameter or outside the objects' shapes, an unknown key, a model
    that does not overlap the data's box (or, in the demo, the scene's), a model with nothing
    free, a model file with the neural image fit, the neural profile fit with no start, a
    bad free material (free not a boolean, fewer than two classes, a start outside them, a
    held one without a start, an unknown or repeated class, an unknown key): one error line
    naming the file and field, exit 2, nothing written."""
    model = tmp_path / "m.toml"
    head = 'name = "m"\n[bounds]\nlower_m = [-0.05, -0.05, -0.05]\nupper_m = [0.05, 0.05, 0.05]\n'
    ball = '[[objects]]\nname = "ball"\nmaterial = "metal"\n[objects.shape]\ntype = "sphere"\nradius_m = 0.01\n'
    args = ["reconstruct", tmp_path / "data.h5", "--out", tmp_path / "run", "--model", "primitive",
            "--scene-model", model, "--bounds", "-0.05,-0.05,-0.05,0.05,0.05,0.05"]
    for body, expected in (
            ('center_m = { free = true }\n', "objects[0].shape.center_m: a parameter table needs a start"),
            ('center_m = { start = [0.04, 0, 0], bounds_m = [[-0.01, -0.01, -0.01], [0.01, 0.01, 0.01]] }\n',
             "objects[0].shape.center_m.start: [0.04, 0, 0] is outside its bounds"),
            ('center_m = { start = [0, 0, 0], step = 1 }\n', "objects[0].shape.center_m: unknown key(s) step"),
            ('half_extents_m = { start = [0.01, 0.01, 0.01] }\n', "objects[0].shape.sphere.half_extents_m: Extra inputs"),
    ):
        model.write_text(head + ball + body)
        line = _refused(args, tmp_path)
        assert f"{model}: " in line and expected in line, line
    for material, expected in (
            ('{ start = "metal", free = "yes" }', "objects[0].material.free: expected true or false"),
            ('{ classes = ["metal"] }', "objects[0].material.classes: expected a list of at least two material names"),
            ('{ start = "brick", classes = ["metal", "wood"] }', "objects[0].material.start: 'brick' is not among"),
            ('{ free = false }', "objects[0].material: a held material needs a start"),
            ('{ classes = ["metal", "unobtainium"] }', "objects[0].material: unknown material 'unobtainium'"),
            ('{ classes = ["metal", "pec"] }', "objects[0].material.classes: a class is named twice"),
            ('{ start = "metal", prior = 1 }', "objects[0].material: unknown key(s) prior"),
    ):
        model.write_text(head + ball.replace('"metal"', material, 1))
        line = _refused(args, tmp_path)
        assert f"{model}: " in line and expected in line, line
    model.write_text(head.replace("lower_m = [-0.05, -0.05, -0.05]", "lower_m = { start = [-0.05, -0.05, -0.05] }")
                     + ball)
    assert "bounds: only the objects' shape parameters may be free" in _refused(args, tmp_path)
    model.write_text(head.replace("0.05", "1.05").replace("-1.05", "0.95") + ball.replace(
        "radius_m = 0.01", "radius_m = 0.01\ncenter_m = [1.0, 1.0, 1.0]"))
    assert "bounds: the model's box" in _refused(args, tmp_path)
    demo = ["demo", "--model", "primitive", "--quick", "--scene-model", model, "--out", tmp_path / "demo"]
    assert "bounds: the model's box" in _refused(demo, tmp_path)  # against the scene's box, before simulating
    model.write_text(head + ball)
    assert "no free parameter, so nothing to fit" in _refused(args, tmp_path)
    line = _refused(["reconstruct", tmp_path / "data.h5", "--out", tmp_path / "run", "--scene-model", model], tmp_path)
    assert "--scene-model and --free-materials: only with --model primitive or hybrid, or --fit-to profiles" in line
    line = _refused(["reconstruct", tmp_path / "data.h5", "--out", tmp_path / "run", "--fit-to", "profiles"], tmp_path)
    assert "--model neural --fit-to profiles needs --scene-model, or --scene" in line, line
    line = _refused(["reconstruct", tmp_path / "data.h5", "--out", tmp_path / "run", "--beams"], tmp_path)
    assert "--beams: only with --fit-to profiles" in line, line
    line = _refused(["reconstruct", tmp_path / "data.h5", "--out", tmp_path / "run", "--transmission"], tmp_path)
    assert "--transmission: only with --fit-to profiles" in line, line
