from pathlib import Path

import pytest
import torch

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


@pytest.fixture
def rng():
    return torch.Generator().manual_seed(0)


@pytest.fixture
def spot_path():
    path = SHARED_DATA / "spot.obj"
    if not path.is_file():
        pytest.skip(f"shared test mesh not found at {path}")
    return path
