import os
import shutil
import sys
from pathlib import Path

import pytest
import torch

from rfsdf.geometry import Grid
from rfsdf.parallel import use_threads
from rfsdf.radar import (
    Acquisition, Measurements, SensingOperator, matched_filter, write_image, write_measurements,
)
from rfsdf.studies.ball_fit import small_radar

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def pytest_configure(config):
    """RFSDF_TEST_THREADS=N runs the suite with N torch and numba threads (torch clamps
    OMP_NUM_THREADS to the core count, so 4 threads on a 2-core machine need this; numba's
    count is at most NUMBA_NUM_THREADS, which `make test` sets to N): a verdict must not depend
    on it (docs/guide/reproducibility.md)."""
    threads = os.environ.get("RFSDF_TEST_THREADS")
    if threads:
        use_threads(int(threads))


# The files whose module fixtures run a long job once (the quick demo, every study, the docs
# site, the two balls' fit): under pytest-xdist (`make test`) each goes whole to one worker, so
# the job runs once; every other test goes to whichever worker is free.
LONG_JOB_FILES = {"test_demo.py", "test_studies.py", "test_docs.py", "test_material_fit.py"}


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """`--dist load` (what `-n` gives) with LONG_JOB_FILES as units; any other --dist as asked."""
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class Scheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            file = nodeid.split("::", 1)[0]
            return file if Path(file).name in LONG_JOB_FILES else nodeid

    return Scheduling(config, log)


def pytest_report_header(config):
    return f"torch threads: {torch.get_num_threads()}"


@pytest.fixture(scope="session")
def tool_environment() -> dict:
    """The environment a test runs a command in: this Python's ``rfsdf``, ``python`` and
    ``mkdocs`` first on the PATH, MkDocs' notice of its next major version off."""
    bin_dir = str(Path(sys.executable).parent)
    return {**os.environ, "PATH": bin_dir + os.pathsep + os.environ.get("PATH", ""), "NO_MKDOCS_2_WARNING": "1"}


@pytest.fixture
def rng():
    return torch.Generator().manual_seed(0)


@pytest.fixture(scope="session")
def tiny_radar():
    """Six views around the origin, a 4 cm boundary array (6 Tx, 6 Rx), 8 frequencies: the fit
    studies' radar."""
    return small_radar()


@pytest.fixture
def spot_path():
    path = SHARED_DATA / "spot.obj"
    if not path.is_file():
        pytest.skip(f"shared test mesh not found at {path}")
    return path


@pytest.fixture
def tiny_files(tmp_path):
    """In tmp_path: data.h5 (a point target seen by 4 single-antenna views), image.h5 (its MF
    image on a 10^3 grid) and tiny.toml (a seconds-long reconstruction config, the warm start alone)."""
    centres = torch.tensor([[0.5, 0, 0], [-0.5, 0, 0], [0, 0.5, 0], [0, -0.5, 0]], dtype=torch.float64)
    acq = Acquisition(centres[:, None], centres[:, None], torch.linspace(77e9, 81e9, 8), -centres / 0.5)
    y = SensingOperator(acq).forward(torch.tensor([[0.01, 0.0, 0.0]]), torch.ones(1, dtype=torch.complex64))
    m = Measurements(acq, y)
    write_measurements(tmp_path / "data.h5", m)
    write_image(tmp_path / "image.h5", matched_filter(m, Grid((-0.05,) * 3, (0.05,) * 3, (10, 10, 10))))
    (tmp_path / "tiny.toml").write_text(
        '[field]\nwidth = 16\ndepth = 3\nlevels = 1\n[render]\nelement_step = 1\nrefresh_every = 3\n'
        '[init]\nmethod = "mf"\nthreshold = 0.06\nsteps = 20\nbatch = 256\nprimitives = false\n'
        '[sampling]\nviews_per_step = 2\ndata_batch = 128\neikonal_batch = 64\n'
        '[train]\nsteps = 6\ncheckpoint_every = 3\nmesh_resolution = 24\n')
    return tmp_path


@pytest.fixture(scope="module")
def browser():
    """A headless Chromium driven by Playwright, closed after its module's tests (left open it
    idled at about 8 % of a core through the rest of the suite); skips, saying why, where none
    can start.

    The set-up (`make test`) installs Debian's chromium. SwiftShader draws WebGL on the CPU."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed (pip install -e '.[test]')")
    executable = shutil.which("chromium") or shutil.which("chromium-browser")
    if executable is None:
        pytest.skip("no Chromium on this machine: the set-up installs it with `apt-get install chromium`, which "
                    "needs root or sudo and Debian's package registry")
    with sync_api.sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=executable, args=[
            "--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--disable-background-networking",
            "--disable-component-update", "--no-first-run"])
        yield chromium
        chromium.close()
