"""Shared test set-up: the repo root on sys.path and the shared test meshes (skipped if absent)."""
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_MESHES = ROOT.parent / "shared" / "meshes"
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@pytest.fixture
def shared_mesh():
    def load(name):
        if not SHARED_MESHES.is_dir():
            pytest.skip(f"shared meshes not found at {SHARED_MESHES} (they live beside the checkout)")
        from lumen_addon.obj import load_obj
        return load_obj(SHARED_MESHES / f"{name}.obj")
    return load
