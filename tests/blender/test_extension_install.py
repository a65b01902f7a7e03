"""The built extension zip installs into Blender like a user's install and its operator works."""
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from blender_runner import blender  # noqa: F401  (fixture)

ROOT = Path(__file__).resolve().parents[2]
EXIT_DOWNLOAD_FAILED = 3   # tools/build_extension.py: a wheel could not be downloaded


@pytest.fixture(scope="module")
def extension_zip():
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "build_extension.py")],
                          capture_output=True, text=True, timeout=600)
    if proc.returncode == EXIT_DOWNLOAD_FAILED:
        pytest.skip(f"bundled wheels could not be downloaded (offline?): {proc.stderr.strip()}")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    tag = f"-py{sys.version_info[0]}{sys.version_info[1]}.zip"     # the zip for this Python
    zips = [z for z in proc.stdout.strip().splitlines() if z.endswith(tag)]
    assert zips, proc.stdout
    zip_path = zips[0]
    return zip_path


def test_zip_contents(extension_zip):
    names = set(zipfile.ZipFile(extension_zip).namelist())
    assert {"blender_manifest.toml", "__init__.py", "operators/bake_op.py",
            "lumen_addon/bake.py", "gpu_shaders/__init__.py"} <= names
    assert any(n.startswith("wheels/embreex-") for n in names)
    leaked = [n for n in names if n.split("/")[0] in
              {"tests", "tools", "bench", "docs", ".venv", ".git", ".ci", "dist", ".gitignore"}
              or "__pycache__" in n]
    assert not leaked, leaked


def test_install_enable_and_bake(extension_zip, blender, tmp_path):
    user = tmp_path / "blender_user"     # BLENDER_USER_RESOURCES of the subprocess (conftest)
    res = blender(f"""
        import importlib, os
        result = bpy.ops.extensions.package_install_files(
            filepath={extension_zip!r}, repo='user_default', enable_on_install=True)
        module = importlib.import_module("bl_ext.user_default.lumen_gi")
        enabled = "bl_ext.user_default.lumen_gi" in bpy.context.preferences.addons
        site = bpy.utils.user_resource('EXTENSIONS', path=".local/lib/python3.11/site-packages")
        # Not read_factory_settings(): that would reset the preferences and disable the add-on.
        for obj in list(bpy.data.objects):
            bpy.data.objects.remove(obj)
        bpy.ops.mesh.primitive_cube_add()
        scene = bpy.context.scene
        scene.lumen.bake.voxel_density = 4.0
        scene.lumen.bake.cache_dir = {str(tmp_path / "cache")!r}
        baked = sorted(bpy.ops.lumen.bake())
        status, objects = scene.lumen.last_bake.status, scene.lumen.last_bake.objects
        wheel_installed = os.path.isdir(os.path.join(site, "embreex"))
        bpy.ops.preferences.addon_disable(module="bl_ext.user_default.lumen_gi")
        unregistered = not any(hasattr(t, n) for t, n in (
            (bpy.types.Scene, "lumen"), (bpy.types.Object, "lumen"), (bpy.types, "LUMEN_OT_bake"),
            (bpy.types, "LUMEN_OT_export_cache"), (bpy.types, "LUMEN_OT_open_atlas"),
            (bpy.types, "VIEW3D_PT_lumen")))
        emit(unregistered=unregistered, install=sorted(result), enabled=enabled, file=module.__file__,
             wheel_installed=wheel_installed,
             wheel_removed=not os.path.isdir(os.path.join(site, "embreex")),
             baked=baked, objects=objects, status=status)
    """, load_addon=False)
    r = res.result
    assert r["install"] == ["FINISHED"] and r["enabled"]
    assert r["file"].startswith(str(user / "extensions" / "user_default" / "lumen_gi"))
    assert r["wheel_installed"], "the bundled embreex wheel was not installed"
    assert r["baked"] == ["FINISHED"] and r["objects"] == 1, r["status"]
    assert (tmp_path / "cache" / "manifest.json").is_file()
    assert r["unregistered"], "disabling the add-on left its properties or operators behind"
    assert r["wheel_removed"], "Blender keeps the wheels of disabled extensions; expected removal"
