"""Run real Blender (the bpy module) in a subprocess per test; test modules import `blender`.

Not a conftest.py: tests/core imports `from conftest import ...`, and a second conftest module
here would shadow tests/conftest.py in sys.modules.

Each test gets a fresh Blender: registration, scene state and module-level caches cannot leak
between tests, a crash shows up as an exit code instead of killing pytest, and Blender's user
resources and temp files go to the test's tmp folder, never to the real user's configuration.
The snippet runs after `PREAMBLE` (add-on loaded from the repo as `lumen_gi`, helpers from
`blender_scenes.py`); it reports back by calling `emit(**json_values)`.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
RESULT_MARK = "@@LUMEN_RESULT "
# Blender prints this for a shader whose push constants exceed the 128 bytes Vulkan guarantees
# (on OpenGL too); every pass must keep within them, so any run that prints it fails.
PUSH_CONSTANT_WARNING = "Push constants have a minimum supported size"

PREAMBLE = f"""
import json, sys
sys.path[:0] = [{str(HERE)!r}, {str(ROOT / 'tools')!r}]
import bpy
import numpy as np
from blender_scenes import *
def emit(**values):
    print({RESULT_MARK!r} + json.dumps(values), flush=True)
"""
LOAD_ADDON = """
import demo
addon = demo.load_addon()
addon.gpu_shaders.engine.KEEP_IMAGES = True   # tests read the frame's images in LAST_RENDER
"""


@dataclass
class BlenderRun:
    returncode: int
    stdout: str
    stderr: str
    result: dict

    def explain(self) -> str:
        return f"exit {self.returncode}\n--- stdout\n{self.stdout[-4000:]}\n--- stderr\n{self.stderr[-4000:]}"


def run_python(snippet: str, tmp_path: Path, *, load_addon: bool = True, timeout: float = 120.0,
               env: dict | None = None) -> BlenderRun:
    """Run `snippet` in a new Python with bpy; returns exit code, output and the emitted values."""
    user = tmp_path / "blender_user"
    temp = tmp_path / "tmp"
    user.mkdir(exist_ok=True)
    temp.mkdir(exist_ok=True)
    full_env = dict(os.environ, BLENDER_USER_RESOURCES=str(user), TMPDIR=str(temp),
                    PYTHONDONTWRITEBYTECODE="1")
    full_env.update(env or {})
    code = PREAMBLE + (LOAD_ADDON if load_addon else "") + textwrap.dedent(snippet)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=timeout, env=full_env, cwd=tmp_path)
    over = [line for line in (proc.stdout + proc.stderr).splitlines() if PUSH_CONSTANT_WARNING in line]
    assert not over, "a shader exceeds Vulkan's 128 push-constant bytes:\n" + "\n".join(over)
    result = {}
    for line in proc.stdout.splitlines():
        if line.startswith(RESULT_MARK):
            result.update(json.loads(line[len(RESULT_MARK):]))
    return BlenderRun(proc.returncode, proc.stdout, proc.stderr, result)


@pytest.fixture
def blender(tmp_path):
    """`blender(snippet, **kw)` runs the snippet in a fresh bpy process and requires exit 0."""
    def run(snippet: str, **kw) -> BlenderRun:
        res = run_python(snippet, tmp_path, **kw)
        assert res.returncode == 0, res.explain()
        return res
    return run
