"""The built zip in every supported Blender: 4.2.0 (oldest, CPython 3.11), 5.0.1 (development) and
5.3.0 (newest, CPython 3.13) on OpenGL and Vulkan, each installing this platform's zip for its
Python into a clean user folder, enabling it, baking the demo scene and rendering F12
(tools/version_matrix.py, tools/smoke_install.py). Every image must equal the 5.0.1 one.

Each leg's Blender is the `bpy` module in its own virtual environment under .venv/versions
(created on first use: ~400 MB downloaded once per version). A leg is skipped, with the reason,
only where its CPython is not on the machine or, for Vulkan, where Mesa's lavapipe is not installed
(`./lumen test` installs it on Debian/Ubuntu)."""
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import version_matrix as vm  # noqa: E402

LEGS = {leg.name: leg for leg in vm.LEGS}
SAME = 1e-4     # relMSE under which two Blenders render the same image


@pytest.fixture(scope="module")
def zips():
    return vm.build_zips()


@pytest.fixture(scope="module")
def reference(zips, tmp_path_factory):
    rep = vm.run_leg(LEGS[vm.REFERENCE], zips["3.11"], tmp_path_factory.mktemp("ref"))
    assert rep["returncode"] == 0, rep["log"]
    return np.load(rep["image"])


def test_zips_per_python_hold_only_their_wheels(zips):
    import zipfile
    assert set(zips) == {"3.11", "3.13"}, zips
    for py, path in zips.items():
        wheels = [n for n in zipfile.ZipFile(path).namelist() if n.endswith(".whl")]
        tag = "cp" + py.replace(".", "")
        assert wheels and all(f"-{tag}-" in w for w in wheels), (path, wheels)
        assert {w.split("/")[-1].split("-")[0] for w in wheels} == {"embreex", "openimageio"}


@pytest.mark.parametrize("name", [n for n in LEGS if n != vm.REFERENCE])
def test_leg_installs_bakes_and_renders_the_same_image(name, zips, reference, tmp_path):
    leg = LEGS[name]
    try:
        rep = vm.run_leg(leg, zips[leg.python], tmp_path)
    except vm.LegSkipped as exc:
        pytest.skip(f"{name}: {exc}")
    assert rep["returncode"] == 0, rep["log"]
    assert rep["install"] == ["FINISHED"] and rep["bake"] == ["FINISHED"], rep
    assert rep["gpu_backend"] == leg.backend, rep
    assert rep["push_constant_warnings"] == 0, rep["log"]
    assert rep.get("passes", 0) >= 40, rep          # every compute pass compiled on this leg
    image = np.load(rep["image"])
    assert image.shape == reference.shape and np.isfinite(image).all()
    err = vm.rel_mse(image, reference)
    assert err < SAME, f"{name}: relMSE {err:.2e} against {vm.REFERENCE}"


SAMPLER_PROBE = textwrap.dedent("""
    import bpy, gpu, json
    class E(bpy.types.RenderEngine):
        bl_idname = "LUMEN_SAMPLER_PROBE"; bl_label = "probe"; bl_use_gpu_context = True
        def render(self, depsgraph):
            names = ("a", "b", "c", "d")
            textures = [gpu.types.GPUTexture((1, 1), format='RGBA32F',
                                             data=gpu.types.Buffer('FLOAT', 4, [i + 1.0] * 4))
                        for i in range(len(names))]
            reads = ", ".join(f"texelFetch({n}, ivec2(0), 0).x" for n in names)
            result = {}
            for guarded in (False, True):
                info = gpu.types.GPUShaderCreateInfo()
                info.local_group_size(1, 1, 1)
                if guarded:   # gpu_shaders.compute.new_info / create / run
                    info.push_constant('INT', 'bind_guard')
                for i, n in enumerate(names):
                    info.sampler(i, 'FLOAT_2D', n)
                info.image(0, 'RGBA32F', 'FLOAT_2D', 'out_image', qualifiers={'WRITE'})
                guard = "if (bind_guard == -1) { return; }" if guarded else ""
                info.compute_source("void main() { " + guard + " imageStore(out_image, ivec2(0), "
                                    "vec4(" + reads + ")); }")
                sh = gpu.shader.create_from_info(info)
                out = gpu.types.GPUTexture((1, 1), format='RGBA32F')
                for n, tex in zip(names, textures):
                    sh.uniform_sampler(n, tex)
                sh.image("out_image", out)
                if guarded:
                    sh.uniform_int("bind_guard", 0)
                gpu.compute.dispatch(sh, 1, 1, 1)
                result["guarded" if guarded else "plain"] = out.read().to_list()[0][0]
            print("@@PROBE " + json.dumps(result))
    bpy.utils.register_class(E)
    bpy.context.scene.render.engine = "LUMEN_SAMPLER_PROBE"
    bpy.ops.render.render()
""")


@pytest.mark.parametrize("name", ["5.3.0", "5.3.0-vulkan", vm.REFERENCE, "4.2.0"])
def test_sampler_binding_and_the_bind_guard(name, tmp_path):
    """Four samplers holding 1, 2, 3, 4 must read back 1, 2, 3, 4. Blender 5.3's OpenGL backend
    writes each `uniform_sampler` call's texture unit into the shader's first uniform too, so
    without a push constant the first sampler reads the last-bound texture ([4, 2, 3, 4]): a
    Blender defect. Our passes carry an int push constant declared first, read and set last
    (gpu_shaders.compute: new_info, create, run), which absorbs those writes: that variant must
    read right on every Blender. The plain variant is an expected failure on 5.3 OpenGL only
    (it passes again once Blender is fixed)."""
    leg = LEGS[name]
    if leg.backend == "VULKAN" and not vm.lavapipe_installed():
        pytest.skip("no Vulkan driver (Mesa lavapipe)")
    try:
        py = vm.ensure_env(leg)
    except vm.LegSkipped as exc:
        pytest.skip(f"{name}: {exc}")
    import json
    import os
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path), **leg.env)
    proc = subprocess.run([py, "-c", SAMPLER_PROBE], capture_output=True, text=True, env=env,
                          timeout=300)
    lines = [l for l in proc.stdout.splitlines() if l.startswith("@@PROBE ")]
    assert lines, proc.stdout[-2000:] + proc.stderr[-2000:]
    values = json.loads(lines[-1][len("@@PROBE "):])
    assert values["guarded"] == [1.0, 2.0, 3.0, 4.0], values
    if name == "5.3.0" and values["plain"] != [1.0, 2.0, 3.0, 4.0]:
        pytest.xfail(f"Blender 5.3 OpenGL: the first sampler reads the last texture: {values['plain']}")
    assert values["plain"] == [1.0, 2.0, 3.0, 4.0]
