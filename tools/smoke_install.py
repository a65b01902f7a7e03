"""Install the built extension zip into a Blender, enable it, bake the demo scene and render F12.

    <python with bpy> tools/smoke_install.py ZIP --out DIR [--size W H]

Runs under any supported Blender's Python (bpy 4.2 with CPython 3.11 up to bpy 5.3 with 3.13), as
an artist's install would: `package_install_files` into the user repository (set
BLENDER_USER_RESOURCES to a clean folder first), enable, then the N-panel's Bake and F12 with the
"Lumen GI" engine. Nothing of the repository is imported but `demo.build_demo_scene` (plain bpy
calls), so the code under test is the installed zip's.

Writes DIR/render.npy (float32 [h, w, 4] of the F12 image, rows bottom-up as Blender stores them)
DIR/passes.npz (the G-buffer, direct and indirect light) and DIR/report.json (Blender and Python versions, install/enable/bake results and the
GPU backend F12 ran on, and how many of the engine's compute passes compiled: all of them are,
not only those the default F12 runs). Exits 1 on any failure with the reason on stderr. Blender picks the
backend itself (tools/version_matrix.py shows how a leg forces OpenGL).
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
MODULE = "bl_ext.user_default.lumen_gi"


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("zip")
    parser.add_argument("--out", required=True)
    parser.add_argument("--size", type=int, nargs=2, default=(96, 72))
    args = parser.parse_args(argv)
    if not os.environ.get("BLENDER_USER_RESOURCES"):
        print("error: set BLENDER_USER_RESOURCES to a clean folder (the install goes there)",
              file=sys.stderr)
        return 1

    import bpy

    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    report = {"blender": bpy.app.version_string, "python": sys.version.split()[0]}

    def fail(message: str) -> int:
        report["error"] = message
        (out / "report.json").write_text(json.dumps(report, indent=1))
        print(f"error: {message}", file=sys.stderr)
        return 1

    result = bpy.ops.extensions.package_install_files(
        filepath=str(Path(args.zip).resolve()), repo="user_default", enable_on_install=True)
    report["install"] = sorted(result)
    if MODULE not in bpy.context.preferences.addons:
        return fail(f"{MODULE} is not enabled after the install ({sorted(result)})")
    addon = importlib.import_module(MODULE)

    sys.path.insert(0, str(HERE))
    import demo   # only its scene builder: plain bpy calls

    scene = demo.build_demo_scene(factory_reset=False)   # keeps the enabled extension
    scene.lumen.bake.cache_dir = str(out / "cache")
    baked = bpy.ops.lumen.bake()
    report["bake"] = sorted(baked)
    report["bake_status"] = scene.lumen.last_bake.status
    if baked != {"FINISHED"}:
        return fail(f"bake returned {sorted(baked)}: {scene.lumen.last_bake.status}")

    scene.render.engine = "LUMEN_GI"
    scene.render.resolution_x, scene.render.resolution_y = args.size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    exr = Path(tempfile.mkdtemp()) / "render.exr"
    scene.render.filepath = str(exr)
    engine = addon.gpu_shaders.engine
    bpy.ops.render.render(write_still=True)
    info = getattr(engine, "LAST_RENDER", {}) or {}
    if info.get("error"):
        return fail(f"F12: {info['error']}")
    report["gpu_backend"] = info.get("gpu_backend", "unknown")
    if not exr.is_file():
        return fail(f"F12 wrote no image at {exr}")
    image = bpy.data.images.load(str(exr))
    import numpy as np
    pixels = np.empty(image.size[0] * image.size[1] * 4, np.float32)
    image.pixels.foreach_get(pixels)
    np.save(out / "render.npy", pixels.reshape(image.size[1], image.size[0], 4))
    # the engine's intermediate images, to tell which pass differs between Blenders
    np.savez(out / "passes.npz", **{k: np.asarray(info[k], np.float32) for k in
                                    ("position", "normal", "albedo", "emission", "direct", "indirect")
                                    if k in info})
    # every compute pass the engine declares, not only those the default F12 runs (importance
    # sampling, the radiance cache, SSGI, RSM, LPV, VXGI...): a Blender whose shader compiler
    # refuses one fails here, not in an artist's hands (Blender 5.3 dropped `shared` declarations)
    report["passes"], failed = compile_every_pass(addon)
    if failed:
        return fail(f"{len(failed)} compute passes do not compile: {failed}")
    (out / "report.json").write_text(json.dumps(report, indent=1))
    print(json.dumps(report))
    return 0


def compile_every_pass(addon) -> tuple:
    """(passes compiled, {name: error} of those that did not), inside a render() that holds
    Blender's GPU context (headless, that is where shaders compile)."""
    import bpy

    compute = importlib.import_module(f"{addon.__name__}.gpu_shaders.compute")
    done, failed = [], {}

    class CompileEngine(bpy.types.RenderEngine):
        bl_idname = "LUMEN_SMOKE_COMPILE"
        bl_label = "Compile every pass (smoke test)"
        bl_use_gpu_context = True

        def render(self, depsgraph):
            for p in compute.declared_passes():
                try:
                    for defines in p.variant_sets():
                        p.shader_of(defines)
                    done.append(p.name)
                except Exception as exc:   # noqa: BLE001 (reported by name)
                    failed[p.name] = str(exc)[:200]
            self.end_result(self.begin_result(0, 0, 4, 4))

    bpy.utils.register_class(CompileEngine)
    scene = bpy.context.scene
    before = scene.render.engine
    try:
        scene.render.engine = CompileEngine.bl_idname
        bpy.ops.render.render()
    finally:
        scene.render.engine = before
        bpy.utils.unregister_class(CompileEngine)
    return len(done), failed


if __name__ == "__main__":
    sys.exit(main())
