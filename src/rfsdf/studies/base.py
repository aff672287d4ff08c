"""What every study shares: its settings in, a typed result out, JSON and a figure written
atomically. A study module defines NAME, SUMMARY, ``Settings`` (a frozen dataclass whose
defaults are the full size), ``QUICK`` (the test-suite size), ``run(settings) -> Result``
and ``plot(result, path)``; :func:`run_study` does the rest."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import ModuleType

from ..jsonio import write_json

__all__ = ["run_study"]


def run_study(study: ModuleType, out, *, quick: bool = False) -> tuple[Path, Path]:
    """Run ``study`` at its full or quick size; write OUT/NAME.json (settings and result)
    and OUT/NAME.png. Returns both paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    settings = study.QUICK if quick else study.Settings()
    result = study.run(settings)
    json_path, png_path = out / f"{study.NAME}.json", out / f"{study.NAME}.png"
    write_json(json_path, {"study": study.NAME, "quick": quick, "settings": dataclasses.asdict(settings),
                           "result": dataclasses.asdict(result)})
    study.plot(result, png_path)
    return json_path, png_path
