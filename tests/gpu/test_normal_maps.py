"""A tangent-space normal map (Image Texture -> Normal Map -> the Principled BSDF's Normal), against
Cycles: a floor whose map tilts the normal 40 degrees towards +x on its left half and leaves it
flat on its right half, under a sun from +x and above; pure Lambert (Specular IOR Level 0), GI
off in ours and no bounces in Cycles.

- our G-buffer's shading normal (packed in the albedo and emission w) on the left half is the
  tilted normal to 1e-3, on the right half +z; its geometric normal is +z on both; the F12
  Normal pass is the shading normal, as Cycles' (within 0.02 of it);
- each half's Diffuse Direct matches Cycles' within 3% (the tilted half is brighter: it faces
  the sun more; both apply Cycles' bump shadowing term, light_lib.glsl bump_shadowing, Conty
  Estevez et al.'s: ours 1.1% over Cycles', 1.0% under with Chiang et al.'s older term, which
  tests/gpu/test_bump.py's 30 degrees put 6.7% under).
Before, the normal map was ignored: both halves shaded as flat (the left 12% darker than Cycles').
"""
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402
from exr_passes import read_pass  # noqa: E402

SIZE = 48
TILT = math.radians(40.0)

# a sun from +x and above, the floor seen from above by an orthographic camera, no world light;
# baked, with the Diffuse Direct pass (test_bump.py shares it)
SUN_OVER_FLOOR = f"""
sun = link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
sun.data.energy = 3.0
sun.data.angle = 0.0
sun.rotation_euler = (0.0, 0.9, 0.0)                  # from +x and above
cam = aimed_camera((0.0, 0.0, 8.0), (0.0, 0.0, 0.0))
cam.data.type = 'ORTHO'
cam.data.ortho_scale = 4.2
scene.world = bpy.data.worlds.new("World")
scene.world.color = (0.0, 0.0, 0.0)
scene.render.resolution_x = scene.render.resolution_y = {SIZE}
scene.render.resolution_percentage = 100
res, err = bake()
assert err is None, err
scene.view_layers[0].use_pass_diffuse_direct = True
"""


def textured_floor(name: str, width: int, height: int) -> str:
    """Snippet: a 4 m grey floor (no specular) whose Principled BSDF has an Image Texture node
    `tex` of a new float, Non-Color image `img` (width x height); `px` its pixels (all ones),
    for the caller to fill, set and link (test_bump.py shares it)."""
    return f"""
import math

scene = empty_scene(voxel_density=8.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=4.0)
floor = bpy.context.object
img = bpy.data.images.new("{name}", {width}, {height}, alpha=False, float_buffer=True)
img.colorspace_settings.name = "Non-Color"
px = np.ones(({height}, {width}, 4), np.float32)
mat = principled("Bumpy", (0.8, 0.8, 0.8))
nodes, links = mat.node_tree.nodes, mat.node_tree.links
bsdf = nodes["Principled BSDF"]
bsdf.inputs["Specular IOR Level"].default_value = 0.0
tex = nodes.new("ShaderNodeTexImage")
tex.image = img
floor.data.materials.append(mat)
"""


SNIPPET = textured_floor("Bumps", 16, 16) + f"""
tilted = np.array([math.sin({TILT}), 0.0, math.cos({TILT})])
px[:, :8, :3] = (tilted + 1.0) / 2.0                  # left half (u < 0.5): tilted towards +x
px[:, 8:, :3] = (np.array([0.0, 0.0, 1.0]) + 1.0) / 2.0
img.pixels.foreach_set(px.ravel())
tex.interpolation = 'Closest'
nmap = nodes.new("ShaderNodeNormalMap")
links.new(tex.outputs["Color"], nmap.inputs["Color"])
links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
""" + SUN_OVER_FLOOR + """
scene.view_layers[0].use_pass_normal = True
R = render_lumen(save=("normal", "albedo", "emission", "position"), quality="OFF", exr="lumen.exr")
render_cycles(16, exr="cycles.exr", bounces=0)
emit(notes=R.get("notes", []))
"""


def oct_decode(u, v):
    """octahedral_lib.glsl's oct_decode in numpy."""
    f = np.stack([u, v], -1) * 2.0 - 1.0
    n = np.concatenate([f, 1.0 - np.abs(f).sum(-1, keepdims=True)], -1)
    t = np.maximum(-n[..., 2:], 0.0)
    n[..., :2] -= np.where(n[..., :2] >= 0.0, 1.0, -1.0) * t
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def test_normal_map_shades_the_floor_as_cycles(tmp_path):
    run = run_python(SNIPPET, tmp_path, timeout=600)
    assert run.returncode == 0, run.explain()
    geometric = np.load(tmp_path / "normal.npy")[..., :3]
    normal = oct_decode(np.load(tmp_path / "albedo.npy")[..., 3],
                        np.load(tmp_path / "emission.npy")[..., 3])     # the shading normal
    pos = np.load(tmp_path / "position.npy")
    ours = read_pass(tmp_path / "lumen.exr", "Diffuse Direct")[::-1]   # rows bottom first
    ref = read_pass(tmp_path / "cycles.exr", "Diffuse Direct")[::-1]
    our_normal = read_pass(tmp_path / "lumen.exr", "Normal")[::-1]
    cycles_normal = read_pass(tmp_path / "cycles.exr", "Normal")[::-1]
    tilted = np.array([math.sin(TILT), 0.0, math.cos(TILT)])
    x, y = pos[..., 0], pos[..., 1]
    floor = (pos[..., 3] > 0.5) & (np.abs(y) < 1.8)
    for name, sel, want in (("left", floor & (x < -0.2) & (x > -1.8), tilted),
                            ("right", floor & (x > 0.2) & (x < 1.8), np.array([0.0, 0.0, 1.0]))):
        assert sel.sum() > 100
        np.testing.assert_allclose(normal[sel], np.tile(want, (sel.sum(), 1)), atol=1e-3)
        np.testing.assert_allclose(geometric[sel], np.tile((0.0, 0.0, 1.0), (sel.sum(), 1)),
                                   atol=1e-6)                # the G-buffer's geometric normal
        # the F12 Normal pass is the shading normal, as Cycles' is
        np.testing.assert_allclose(our_normal[sel].mean(0), want, atol=1e-3)
        np.testing.assert_allclose(cycles_normal[sel].mean(0), want, atol=0.02)
        a, b = ours[sel].mean(), ref[sel].mean()
        print(name, "ours", a, "cycles", b)
        assert abs(a / b - 1.0) < 0.03, (name, a, b)
