"""Sweeps: the jobs a file names, the local pool and Ray giving the same rows, resuming, failures."""

import json
import math
import re

import pytest
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.errors import RfsdfError
from rfsdf.sweep import load_sweep, run_sweep

# The smallest job that still runs every stage of the demo: the quick settings on one
# sphere, seen by a toy radar (6 views of a 2 cm array, 10 Tx, 10 Rx, 8 frequencies).
_TINY = """
[defaults]
quick = true
scene = "sphere"
radar = "tiny.toml"
recon = { init = { steps = 10 }, train = { steps = 2, checkpoint_every = 1 } }
"""
_TINY_RADAR = ('name = "tiny"\n[waveform]\nkind = "ofdm"\ncarrier_hz = 79e9\nbandwidth_hz = 4e9\nsubcarriers = 8\n'
               '[array]\nkind = "boundary"\nsize_m = 0.02\nelements_per_edge = 5\n'
               '[views]\ndistance_m = 0.3\nazimuths_per_ring = [4, 1, 1]\nelevations_rad = [0.0, 1.4, -1.4]\n'
               '[noise]\nsnr_db = 40.0\n')


def _write(path, text):
    path.write_text(text)
    if text.startswith(_TINY):
        (path.parent / "tiny.toml").write_text(_TINY_RADAR)
    return path


def test_sweep_file_expands_grid_and_listed_jobs(tmp_path):
    (tmp_path / "scenes").mkdir()
    _write(tmp_path / "scenes" / "mine.toml", 'name = "mine"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\n'
           'upper_m = [0.1, 0.1, 0.1]\n[[objects]]\nname = "ball"\nmaterial = "metal"\n'
           'shape = { type = "sphere", radius_m = 0.02 }\n')
    jobs = load_sweep(_write(tmp_path / "s.toml", """
[defaults]
quick = true
recon = { train = { steps = 3 } }
[grid]
scene = ["objects", "sphere"]
seed = [0, 7]
[[jobs]]
scene = "scenes/mine.toml"
radar = "dense-77g"
recon = { init = { threshold = 0.12 } }
"""))
    assert [j.name for j in jobs] == ["000-objects-near-77g-seed0", "001-objects-near-77g-seed7",
                                      "002-sphere-near-77g-seed0", "003-sphere-near-77g-seed7",
                                      "004-mine-dense-77g-seed0"]
    assert jobs[1].settings.seed == 7 and jobs[1].settings.voxel_m == 0.015  # quick
    assert jobs[4].settings.scene == str((tmp_path / "scenes" / "mine.toml").resolve())
    # Listed recon tables merge into the defaults and the quick settings, key by key.
    recon = jobs[4].settings.recon
    assert recon["init"]["threshold"] == 0.12 and recon["init"]["steps"] == 40 and recon["train"]["steps"] == 3


@pytest.mark.parametrize("text, message", [
    ("[grid]\nsceen = ['objects']", "grid: unknown job key(s) sceen; known: scene, radar"),
    ("[grid]\nseed = []", "every grid list needs at least one value"),
    ("[[jobs]]\nseed = -1", "job 0: seed: Input should be greater than or equal to 0"),
    ("title = 'x'", "title: Extra inputs are not permitted"),
    ("", "no jobs"),
])
def test_bad_sweep_files_are_one_line(tmp_path, text, message):
    with pytest.raises(RfsdfError, match=re.escape(message)):
        load_sweep(_write(tmp_path / "bad.toml", text))


def _differences(first: list[dict], second: list[dict]) -> list[str]:
    """Where two lists of rows differ: 'job key: a != b'. Floats agree to 1e-4, relative or
    absolute: two processes may sum in another order (a pool's spawned workers and Ray's
    differ in the last digits), and a sample that sits on the F-score threshold then falls
    either side of it (one of 50,000 moves a fraction by 2e-5). Two seeds differ by percents."""
    def same(a, b) -> bool:
        if isinstance(a, float) and isinstance(b, float):
            return math.isclose(a, b, rel_tol=1e-4, abs_tol=1e-4) or (math.isnan(a) and math.isnan(b))
        return a == b

    if len(first) != len(second):
        return [f"{len(first)} rows != {len(second)}"]
    return [f"{a.get('job')} {k}: {a.get(k)!r} != {b.get(k)!r}" for a, b in zip(first, second)
            for k in sorted(a.keys() | b.keys()) if not same(a.get(k), b.get(k))]


def _metrics(rows, out):
    """The rows without their timings and status, the output folder in error lines as OUT."""
    return [{k: v.replace(str(out), "OUT") if k == "error" else v for k, v in row.items()
             if not k.startswith("time.") and k not in ("status", "seconds_per_step")} for row in rows]


_DIVERGES = "[[jobs]]\nrecon = { train = { lr = 1e30, lr_end = 1e29 } }\n"  # valid settings; the fit's loss turns NaN


def test_pool_and_ray_give_the_same_rows_a_failure_is_a_row_and_a_rerun_reuses_finished_jobs(tmp_path):
    jobs = load_sweep(_write(tmp_path / "s.toml", _TINY + "[grid]\nseed = [0, 1]\n" + _DIVERGES))
    pool = run_sweep(jobs, tmp_path / "pool", workers=2, log=lambda _: None)
    assert [r["status"] for r in pool] == ["done", "done", "failed"]
    assert pool[0]["neural.full.chamfer_l1_mm"] != pool[1]["neural.full.chamfer_l1_mm"]  # two seeds, two fits
    assert pool[2]["error"].startswith("RfsdfError: step 1: loss is not finite")
    assert "\n" not in pool[2]["error"]
    csv_lines = (tmp_path / "pool" / "summary.csv").read_text().splitlines()
    assert csv_lines[0].startswith("job,scene,radar,seed") and len(csv_lines) == 4 and ",failed," in csv_lines[3]
    assert (tmp_path / "pool" / "summary.png").stat().st_size > 0

    ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'rfsdf[cluster]')")
    # Ray runs the second seed and the failure (one fit fewer: the suite's time), 1 thread each
    on_ray = run_sweep(jobs[1:], tmp_path / "ray", workers=2, ray_address="local", log=lambda _: None)
    assert not ray.is_initialized()  # the instance it started is shut down, not left running
    differences = _differences(_metrics(on_ray, tmp_path / "ray"), _metrics(pool[1:], tmp_path / "pool"))
    assert not differences, differences
    summary = json.loads((tmp_path / "ray" / "summary.json").read_text())
    assert summary["rows"] == json.loads(json.dumps(on_ray))

    # A sweep killed during its second job: the rerun reuses the first, runs only the
    # second (reading its data back and reusing its finished fit from the checkpoint left).
    (tmp_path / "pool" / jobs[1].name / "metrics.json").unlink()
    fit_log = tmp_path / "pool" / jobs[1].name / "run" / "log.csv"
    steps_logged = fit_log.read_text().count("\n")
    rerun = run_sweep(jobs, tmp_path / "pool", workers=2, log=lambda _: None)
    assert [r["status"] for r in rerun] == ["reused", "done", "failed"]
    assert fit_log.read_text().count("\n") == steps_logged  # the finished fit was reused, not run again
    assert _metrics(rerun, tmp_path / "pool") == _metrics(pool, tmp_path / "pool")


@pytest.mark.parametrize("job, message", [
    ("radar = 'no-such-radar'", "job 001-sphere-no-such-radar-seed0: no-such-radar: no such radar file or preset"),
    ("recon = { train = { steps = -5 } }", "job 001-sphere-tiny-seed0: recon: train.steps: Input should be greater than 0"),
    ("recon = { init = { method = 'mf' } }", "job 001-sphere-tiny-seed0: recon: init: threshold \"auto\" is the CLEAN"),
    ("scene = 'no-such-scene'", "job 001-no-such-scene-tiny-seed0: no-such-scene: no such scene file or preset"),
])
def test_every_jobs_settings_are_checked_before_the_first_runs(tmp_path, job, message):
    """A bad job anywhere in the file (here the second) stops the sweep before the first job."""
    sweep = _write(tmp_path / "s.toml", _TINY + f"[[jobs]]\n[[jobs]]\n{job}\n")
    result = CliRunner().invoke(main, ["sweep", str(sweep), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2 and result.output.count("\n") == 1, result.output
    assert result.output.startswith(f"error: {sweep}: {message}"), result.output
    assert not (tmp_path / "o").exists()


def test_a_sweeps_size_is_counted_before_it_is_expanded(tmp_path):
    """10^12 jobs are refused in a second, from the list lengths; --max-jobs moves the limit."""
    values = lambda n: "[" + ", ".join(map(str, range(n))) + "]"  # noqa: E731
    huge = _write(tmp_path / "huge.toml", f"[grid]\nseed = {values(10_000)}\nvoxel_m = {values(10_000)}\n"
                                          f"quick = {['true'] * 10_000}\n".replace("'", ""))
    with pytest.raises(RfsdfError, match=re.escape("grid: asks for 1,000,000,000,000 jobs (10000 seed x 10000 "
                                                   "voxel_m x 10000 quick), more than the 5,000 allowed")):
        load_sweep(huge)
    three = _write(tmp_path / "three.toml", "[grid]\nseed = [0, 1, 2]\n[[jobs]]\n")
    with pytest.raises(RfsdfError, match=re.escape("asks for 4 jobs (3 seed + 1 listed), more than the 3 allowed")):
        load_sweep(three, max_jobs=3)
    assert len(load_sweep(three, max_jobs=4)) == 4
    result = CliRunner().invoke(main, ["sweep", str(three), "--out", str(tmp_path / "o"), "--max-jobs", "2"])
    assert result.exit_code == 2 and "raise the limit with --max-jobs" in result.output
    assert not (tmp_path / "o").exists()


def test_a_sweep_with_a_failed_job_exits_1(tmp_path):
    """A failure that only shows when the job runs (here a file where its folder goes; a fit
    that diverges is another, above) is a row of the summary and exit status 1."""
    sweep = _write(tmp_path / "s.toml", _TINY + "[[jobs]]\n")
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "000-sphere-tiny-seed0").write_text("in the way")
    result = CliRunner().invoke(main, ["--quiet", "sweep", str(sweep), "--out", str(tmp_path / "o")])
    assert result.exit_code == 1, result.output
    assert "000-sphere-tiny-seed0: failed FileExistsError" in result.output
    assert "(0 finished, 1 failed)" in result.output and (tmp_path / "o" / "summary.csv").is_file()


def test_sweep_command_reports_bad_files_in_one_line(tmp_path):
    bad = _write(tmp_path / "bad.toml", "[grid]\nseed = 'zero'\n")
    result = CliRunner().invoke(main, ["sweep", str(bad), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0 and result.output.startswith(f"error: {bad}: grid.seed")
    assert not (tmp_path / "o").exists()
