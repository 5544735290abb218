"""Shared fixtures: the repository, the shared real data and the CLI binary.

The real data live beside the repository (``../shared/data/real/`` from its root, as the Rust
tests find them from ``tools/``: ``../../shared/data/real``); tests that need them are skipped
when they are absent. The CLI (``beamtool``) is the one ``cargo`` built in ``tools/target``
(``BEAMTOOL`` overrides); tests that need it are skipped when there is none.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path
from typing import Optional

import pytest

REPO = Path(__file__).resolve().parents[2]

# Test the installed package (the wheel), not the source directory beside it: `python -m
# pytest` run from python/ puts python/ first on sys.path, where beamshaper/ has no extension.
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != REPO / "python"]
REAL = REPO.parent / "shared" / "data" / "real"
ALUMINIUM = REAL / "aluminium-cantilever"
DECAYS = {
    "40cm": ALUMINIUM / "40cm_adxl_08-12_11-42-08_adxl6cmfromtip2cmID.npy",
    "50cm": ALUMINIUM / "50cm_adxl_08-12_11-47-59_adxl6cmfromtip2cmID.npy",
    "60cm": ALUMINIUM / "60cm_adxl_08-12_21-22-38_4cmID.npy",
}
STEEL_LVM = REAL / "steel-cantilever" / "FFT_data_impulse_test.lvm"
PAPER_RIG = REPO / "rigs" / "paper.toml"


def beamtool() -> Optional[Path]:
    """The newest ``beamtool`` binary of this checkout (any profile), or ``$BEAMTOOL``."""
    env = os.environ.get("BEAMTOOL")
    if env:
        return Path(env)
    found = [p for p in (REPO / "tools" / "target").glob("**/beamtool") if p.is_file() and os.access(p, os.X_OK)]
    found = [p for p in found if p.parent.name in ("release", "debug")]
    if found:
        return max(found, key=lambda p: p.stat().st_mtime)
    on_path = shutil.which("beamtool")
    return Path(on_path) if on_path else None


@pytest.fixture
def real_dir() -> Path:
    if not ALUMINIUM.is_dir():
        pytest.skip(f"real data not present at {REAL}")
    return ALUMINIUM


@pytest.fixture
def cli() -> Path:
    b = beamtool()
    if b is None:
        pytest.skip("no beamtool binary (cd tools && cargo build --release)")
    return b
