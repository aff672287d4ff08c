"""A run folder's files: ``checkpoint.pt`` (data only), ``config.toml`` and ``log.csv``.

Checkpoints are written atomically and hold tensors, numbers, strings and containers only,
so they load with ``torch.load(weights_only=True)``: a crafted checkpoint cannot run code.
"""

from __future__ import annotations

import csv
import pickle
from pathlib import Path

import tomli_w
import torch

from ..atomic import atomic_path
from ..errors import RfsdfError
from ..field import RadarField
from ..limits import input_file

__all__ = ["CHECKPOINT_NAME", "CONFIG_NAME", "LOG_NAME", "save_checkpoint", "read_checkpoint", "write_config",
           "write_log", "read_log", "load_field"]

CHECKPOINT_NAME = "checkpoint.pt"
CONFIG_NAME = "config.toml"
LOG_NAME = "log.csv"


def save_checkpoint(run_dir, state: dict) -> Path:
    """Write ``state`` as ``run_dir/checkpoint.pt``, atomically."""
    path = Path(run_dir) / CHECKPOINT_NAME
    with atomic_path(path) as tmp:
        torch.save(state, tmp)
    return path


def read_checkpoint(path, device) -> dict:
    """The state dict of a checkpoint file, loaded as data only.

    ``weights_only=True``: the unpickler accepts tensors, numbers, strings and containers
    and refuses everything else, so a crafted checkpoint cannot run code (a plain
    ``torch.load`` would execute whatever a pickle in the file asks for).
    """
    path = input_file(path)
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except pickle.UnpicklingError:
        raise RfsdfError(f"{path}: not a readable rfsdf checkpoint (it holds objects other than tensors, "
                         "numbers and strings; refused without running them)") from None
    except Exception as exc:  # noqa: BLE001 - any other failure to read it means "not a checkpoint"
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise RfsdfError(f"{path}: not a readable rfsdf checkpoint ({reason})") from None
    if not isinstance(state, dict):
        raise RfsdfError(f"{path}: not a readable rfsdf checkpoint (holds a {type(state).__name__}, not a dict)")
    return state


def write_config(run_dir, config) -> Path:
    """Write a resolved config (a pydantic model) as ``run_dir/config.toml``, atomically."""
    path = Path(run_dir) / CONFIG_NAME
    with atomic_path(path) as tmp:
        tmp.write_text(tomli_w.dumps(config.model_dump(exclude_none=True)))
    return path


def write_log(run_dir, rows: list[dict]) -> Path:
    """Write the per-step log (one dict per step, same keys) as ``run_dir/log.csv``, atomically."""
    path = Path(run_dir) / LOG_NAME
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        if rows:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    return path


def read_log(run_dir) -> list[dict[str, float]]:
    """The rows of ``run_dir/log.csv`` as numbers (one dict per step); RfsdfError on a bad file."""
    path = input_file(Path(run_dir) / LOG_NAME)
    try:
        with open(path, newline="") as fh:
            return [{key: float(value) for key, value in row.items()} for row in csv.DictReader(fh)]
    except (ValueError, TypeError, csv.Error) as exc:
        raise RfsdfError(f"{path}: not a readable log ({exc})") from None


def load_field(run_dir, device="cpu") -> RadarField:
    """The trained field of a run folder (from its checkpoint), on ``device``, in eval mode."""
    path = Path(run_dir) / CHECKPOINT_NAME
    if not path.is_file():
        raise RfsdfError(f"{run_dir}: no {CHECKPOINT_NAME}; is this a run folder from `rfsdf reconstruct`?")
    state = read_checkpoint(path, "cpu")
    try:
        field = RadarField(**state["field_kwargs"])
        field.load_state_dict(state["field"])
    except (RuntimeError, KeyError, TypeError) as exc:
        raise RfsdfError(f"{path}: not a readable rfsdf checkpoint ({exc})") from None
    return field.to(device).eval()
