"""Data passes as Cycles writes them (View Layer > Passes: Z, Mist, Position, Emission), F12 of
the same scene by both engines written as multilayer EXRs and compared pass by pass: a floor, a
cube and an emitting cube, mist Start 2 m, Depth 10 m, Linear.

- Depth: the distance along the view axis, within 0.5% of Cycles' at the surfaces' pixels away
  from edges, and Cycles' 1e10 where no surface is;
- Mist: within 0.01 (1 where no surface is);
- Position: within 1 cm; Emission: the emitting cube's emission within 1%, 0 elsewhere.
Before, the compositor had none of these passes from Lumen GI.
"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

SIZE = 48

SNIPPET = f"""
scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=12.0)
bpy.context.object.data.materials.append(principled("Floor", (0.8, 0.8, 0.8)))
cube("Box", 1.0, (0.0, 0.0, 0.5)).data.materials.append(principled("Box", (0.5, 0.5, 0.5)))
cube("Lamp", 0.6, (1.6, 0.8, 0.3)).data.materials.append(
    principled("Lamp", (0.0, 0.0, 0.0), emission=(1.0, 0.5, 0.25), strength=4.0))
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 2.0
aimed_camera((3.0, -6.0, 4.0), (0.0, 0.0, 0.3))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
w.mist_settings.start, w.mist_settings.depth, w.mist_settings.falloff = 2.0, 10.0, 'LINEAR'
layer = scene.view_layers[0]
layer.use_pass_z = layer.use_pass_mist = layer.use_pass_position = layer.use_pass_emit = True
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err
R = render_lumen(exr="lumen.exr")
render_cycles(4, exr="cycles.exr")
emit(written=R["passes_written"])
"""


def layers(path) -> dict:
    import OpenImageIO as oiio
    out = {}
    first = oiio.ImageBuf(str(path))
    for k in range(first.nsubimages):
        buf = oiio.ImageBuf(str(path), k, 0)
        names = buf.spec().channelnames
        out[names[0].split(".")[-2]] = buf.get_pixels(oiio.FLOAT)
    return out


def test_depth_mist_position_and_emission_passes_as_cycles(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    assert {"Depth", "Mist", "Position", "Emission"} <= set(run.result["written"])
    ours, ref = layers(tmp_path / "lumen.exr"), layers(tmp_path / "cycles.exr")
    print(sorted(ours), sorted(ref))
    depth, cdepth = ours["Depth"][..., 0], ref["Depth"][..., 0]
    sky = cdepth > 1e9
    assert sky.any() and (~sky).any()
    np.testing.assert_array_equal(depth > 1e9, sky)
    # surface pixels whose 3x3 neighbourhood has one depth (no edge between them)
    pad = np.pad(cdepth, 1, mode="edge")
    stack = np.stack([pad[1 + dy:1 + dy + SIZE, 1 + dx:1 + dx + SIZE]
                      for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    smooth = (~sky) & (np.ptp(stack, axis=0) < 0.05 * cdepth)
    assert smooth.sum() > 0.3 * SIZE * SIZE
    rel = np.abs(depth[smooth] / cdepth[smooth] - 1.0)
    print("depth rel error max", rel.max(), "median", np.median(rel))
    assert rel.max() < 0.005
    mist, cmist = ours["Mist"][..., 0], ref["Mist"][..., 0]
    assert np.all(mist[sky] == 1.0)
    print("mist error max", np.abs(mist - cmist)[smooth].max())
    assert np.abs(mist - cmist)[smooth].max() < 0.01
    pos, cpos = ours["Position"][..., :3], ref["Position"][..., :3]
    assert np.abs(pos - cpos)[smooth].max() < 0.01
    emit_, cemit = ours["Emission"][..., :3], ref["Emission"][..., :3]
    lamp = smooth & (np.abs(cemit[..., 0] - 4.0) < 0.04)      # wholly on the lamp
    assert lamp.sum() > 5
    np.testing.assert_allclose(emit_[lamp], cemit[lamp], rtol=0.01)
    dark = smooth & (cemit.max(-1) == 0.0)
    assert dark.sum() > 50 and np.all(emit_[dark] == 0.0)
