"""screen_probe_fallback: the pixels screen_probe_integrate cannot serve from probes are listed
(fb_list, fb_counter) and traced in their own pass, with exactly the rays, seeds and sums the
integrate pass used to trace inline (llvmpipe, bpy in a subprocess).

Boxes on a floor at 64 px with adaptive probes off (many silhouette pixels without a visible
probe), F12 of 2 frames, with and without the world radiance cache. After each gather the test
reads the list back and runs the old inline gather (the integrate pass's former fallback branch,
below as a test shader) over every pixel: at every listed pixel the frame's E equals it exactly,
each listed pixel is flagged w = 0 and listed once, and there are enough of them to mean something.
The budget (a list longer than the uniform probes' rays allow traces m < 16 rays a pixel, strata
rotating over 16 / m frames): the pass with a budget of 4 rays a pixel, run over the 4 frames of
one cycle, averages exactly the inline pass's 16 rays of that cycle's rotation (sums to 1e-5).
Over the budget even at 1 ray a pixel (a budget of a quarter of the list), from the viewport's
second round each pixel traces on exactly one of 4 consecutive turns and writes w = -2 on the
others; in the first round (fb_round 0) and in F12 (-1) every pixel traces.
The viewport applies that skip in integrate (fb_skip, from the last redraw's list): with fb_skip
4, over 4 turns each pixel of the list is listed on exactly one turn, and written w = -2 on the
others.
"""
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "blender")]

from blender_runner import run_python  # noqa: E402

INLINE = r'''
#include "sdf_lib.glsl"
#include "surface_cache_lib.glsl"
#include "gbuffer_lib.glsl"
#include "sampling_lib.glsl"
#include "radiance_cache_layout_lib.glsl"
#include "radiance_cache_trace_lib.glsl"
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(px, imageSize(out_image)))) {
    return;
  }
  vec3 p, n;
  if (!gbuf_surface(px, cam_pos, p, n)) {
    imageStore(out_image, px, vec4(0.0, 0.0, 0.0, -1.0));
    return;
  }
  float h;
  int obj;
  sdf_scene(p, h, obj);
  float voxel = gi_object_voxel(max(obj, 0));
  vec3 near = sc_near_emission(p, n, voxel);
  uint seed = pcg_hash(uint(px.x) + 7919u * uint(px.y)) ^ pcg_hash(uint(frame) + 0x2545f491u);
  vec2 rot = vec2(float(seed & 0xffffu), float(seed >> 16u)) / 65536.0;
  vec3 o = p + n * max(voxel, 1e-3);
  vec3 sum = vec3(0.0);
  int k = rc_level(o);
  for (int i = 0; i < 16; i++) {
    vec3 dir = cosine_hemisphere(fract(hammersley(uint(i), 16u) + rot), n);
    float t;
    int status;
    sum += rc_radiance(o, dir, t_max, k, t, status);
  }
  imageStore(out_image, px, vec4(3.14159265358979 * sum / 16.0 + near, 0.0));
}
'''

SCRIPT = """
import dataclasses
import mathutils
from lumen_gi.gpu_shaders import engine, gi_settings, compute, radiance_cache, screen_probes

SRC = %r
INLINE = compute.Pass("test_inline_fallback", source=SRC,
                      samplers=screen_probes.GBUF + radiance_cache.SAMPLERS,
                      push=(('VEC3', 'cam_pos'), ('INT', 'frame'), ('FLOAT', 't_max'),
                            radiance_cache.CAMERA))
# an R32I texture reads back as zeros (Blender 5.0): the counter is copied to a float image
COUNT = compute.Pass("test_fallback_count", source='''
void main()
{
  imageStore(out_image, ivec2(0, 0), vec4(float(imageLoad(fb_counter, ivec2(0, 0)).x)));
}
''', images=("out_image", ("fb_counter", 'R32I', {'READ'})))
INLINE_BARE = compute.Pass("test_inline_fallback_bare",
                           source=SRC.replace("+ near, 0.0)", ", 0.0)"),
                           samplers=screen_probes.GBUF + radiance_cache.SAMPLERS,
                           push=(('VEC3', 'cam_pos'), ('INT', 'frame'), ('FLOAT', 't_max'),
                                 radiance_cache.CAMERA))
screen_probes.FALLBACK_BUDGET = 1e6      # 16 rays for every listed pixel
CFG = {}
ROWS = []
_settings = gi_settings.from_scene
gi_settings.from_scene = lambda s, viewport=False: dataclasses.replace(_settings(s, viewport), **CFG)
_gather = screen_probes.ScreenProbes.gather

def _wrapped(self, res, gsdf, cache, gbuf, cam_pos, sky, frame, t_max, voxels=None,
             rcache=None, **kw):
    out = _gather(self, res, gsdf, cache, gbuf, cam_pos, sky, frame, t_max, voxels, rcache, **kw)
    E = compute.read(out)
    counted = compute.texture((1, 1))
    COUNT.run_groups(1, fb_counter=self.textures["fb_counter"], out_image=counted)
    count = int(compute.read(counted).reshape(-1)[0])
    lst = compute.read(self.textures["fb_list"]).reshape(-1, 4)[:count]
    ref = compute.texture((self.width, self.height))
    g = gbuf["textures"]
    lookup = radiance_cache.lookup_inputs(rcache, cam_pos)
    lookup.pop("rc_marks")
    INLINE.run((self.width, self.height), scene=res, cache=cache, gsdf=gsdf, sky=sky,
               voxels=voxels, gbuf_position=g["position"], gbuf_normal=g["normal"],
               cam_pos=compute.vec(cam_pos), frame=int(frame), t_max=float(t_max),
               out_image=ref, **lookup)
    R = compute.read(ref)
    xs, ys = lst[:, 0].astype(int), lst[:, 1].astype(int)
    # the budget: 4 rays a pixel over the 4 frames of cycle `frame`, onto zero (no near light)
    INLINE_BARE.run((self.width, self.height), scene=res, cache=cache, gsdf=gsdf, sky=sky,
                    voxels=voxels, gbuf_position=g["position"], gbuf_normal=g["normal"],
                    cam_pos=compute.vec(cam_pos), frame=int(frame), t_max=float(t_max),
                    out_image=ref, **lookup)
    R16 = compute.read(ref)[ys, xs, :3]
    mean = np.zeros_like(R16)
    for f in range(4 * int(frame), 4 * int(frame) + 4):
        part = compute.texture((self.width, self.height))
        screen_probes.FALLBACK.run(self.textures["fb_list"].width * self.textures["fb_list"].height,
                                   scene=res, cache=cache, gsdf=gsdf, sky=sky, voxels=voxels,
                                   frame=f, t_max=float(t_max), fb_budget=4 * count,
                                   fb_turn=f, fb_round=-1,
                                   gbuf_position=g["position"], gbuf_normal=g["normal"],
                                   cam_pos=compute.vec(cam_pos), out_image=part,
                                   fb_list=self.textures["fb_list"],
                                   fb_counter=self.textures["fb_counter"],
                                   **radiance_cache.lookup_inputs(rcache, cam_pos))
        mean += compute.read(part)[ys, xs, :3] / 4.0
    budget_diff = float(np.abs(mean - R16).max() / max(R16.max(), 1e-9)) if count else -1.0
    # over the budget at 1 ray a pixel, in the viewport's later rounds: with a budget of a
    # quarter of the list, each pixel traces on exactly one turn of four (w 0), else w -2
    traced = np.zeros(len(xs), int)
    every = {}
    for f, fb_round in ((0, 1), (1, 1), (2, 1), (3, 1), (0, 0), (0, -1)):
        part = compute.texture((self.width, self.height))
        screen_probes.FALLBACK.run(self.textures["fb_list"].width * self.textures["fb_list"].height,
                                   scene=res, cache=cache, gsdf=gsdf, sky=sky, voxels=voxels,
                                   frame=f, t_max=float(t_max), fb_budget=-(-count // 4),
                                   fb_turn=f, fb_round=fb_round,
                                   gbuf_position=g["position"], gbuf_normal=g["normal"],
                                   cam_pos=compute.vec(cam_pos), out_image=part,
                                   fb_list=self.textures["fb_list"],
                                   fb_counter=self.textures["fb_counter"],
                                   **radiance_cache.lookup_inputs(rcache, cam_pos))
        flags = compute.read(part)[ys, xs, 3]
        if fb_round >= 1:
            traced += flags == 0.0
            skipped_ok = bool(np.isin(flags, (0.0, -2.0)).all())
        else:
            every[fb_round] = bool((flags == 0.0).all())     # no turn skipped
    # the same skip applied in integrate (fb_skip 4, the viewport's later rounds): over 4 turns
    # each of the listed pixels is listed on exactly one, with w 0, and written w -2 on the
    # others; no other pixel changes its list membership
    listed_turns = np.zeros((self.height, self.width), int)
    pre_flags_ok = True
    for f in range(4):
        img = compute.texture((self.width, self.height))
        lst2 = compute.texture((self.textures["fb_list"].width, self.textures["fb_list"].height))
        cnt2 = compute.texture((1, 1), 'R32I')
        cnt2.clear(format='INT', value=(0,))
        screen_probes.INTEGRATE.run((self.width, self.height), scene=res, cache=cache,
                                    px_step=1, px_phase=(0, 0), gbuf_position=g["position"],
                                    gbuf_normal=g["normal"], gbuf_albedo=g["albedo"],
                                    gbuf_emission=g["emission"], probe_info=self.textures["info"],
                                    probe_normal=self.textures["normal"],
                                    probe_sh=self.textures["sh"], probe_occ=self.textures["occ"],
                                    cam_pos=compute.vec(cam_pos), probe_tile=self.tile,
                                    uniform_rows=0, out_image=img, fb_list=lst2, fb_counter=cnt2,
                                    fb_turn=f, fb_skip=4, shading_normals=0)
        counted2 = compute.texture((1, 1))
        COUNT.run_groups(1, fb_counter=cnt2, out_image=counted2)
        n2 = int(compute.read(counted2).reshape(-1)[0])
        l2 = compute.read(lst2).reshape(-1, 4)[:n2]
        listed_turns[l2[:, 1].astype(int), l2[:, 0].astype(int)] += 1
        w2 = compute.read(img)[ys, xs, 3]
        pre_flags_ok = pre_flags_ok and bool(np.isin(w2, (0.0, -2.0)).all())
    pre_once = bool((listed_turns[ys, xs] == 1).all()) and int(listed_turns.sum()) == count
    ROWS.append(dict(count=count, unique=len(set(zip(xs.tolist(), ys.tolist()))),
                     w_zero=bool((E[ys, xs, 3] == 0).all()),
                     max_diff=float(np.abs(E[ys, xs, :3] - R[ys, xs, :3]).max()) if count else -1.0,
                     max_E=float(E[ys, xs, :3].max()) if count else 0.0,
                     budget_diff=budget_diff,
                     skip_once=bool((traced == 1).all()) if count else False,
                     skip_flags=skipped_ok, first_round_all=every[0], f12_all=every[-1],
                     pre_once=pre_once, pre_flags=pre_flags_ok))
    return out

screen_probes.ScreenProbes.gather = _wrapped
gi_settings.MIN_PROBES_ACROSS = 4      # keep 16 px tiles at 64 px
scene = empty_scene(voxel_density=16.0, cache_dir="cache")
bpy.ops.mesh.primitive_plane_add(size=4.0)
bpy.context.object.data.materials.append(principled("Floor", (0.6, 0.6, 0.6)))
for i, (x, y, s) in enumerate(((-0.5, 0.2, 0.5), (0.4, -0.2, 0.3), (0.6, 0.7, 0.6))):
    bpy.ops.mesh.primitive_cube_add(size=s, location=(x, y, s / 2))
    bpy.context.object.data.materials.append(principled("Box%%d" %% i, (0.7, 0.3, 0.2)))
w = bpy.data.worlds.new("World")
scene.world = w
w.use_nodes = True
w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.8, 0.9, 1.0, 1.0)
cam = link(bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam")))
scene.camera = cam
cam.location = (0.3, -2.6, 1.4)
cam.rotation_euler = (mathutils.Vector((0.1, 0.2, 0.2)) - cam.location).to_track_quat(
    "-Z", "Y").to_euler()
cam.data.lens = 30.0
res, err = bake()
assert err is None, err
scene.render.engine = "LUMEN_GI"
scene.render.resolution_x = scene.render.resolution_y = 64
scene.render.resolution_percentage = 100
scene.lumen.engine.render_quality = "LOW"
scene.lumen.engine.render_frames = 2
scene.lumen.engine.bounces = 1
out = {}
for name, rc in (("plain", False), ("radiance_cache", True)):
    CFG.clear()
    CFG.update(adaptive_probes=False, radiance_cache=rc)
    ROWS.clear()
    bpy.ops.render.render()
    assert "error" not in engine.LAST_RENDER, engine.LAST_RENDER.get("traceback")
    out[name] = list(ROWS)
emit(**out)
""" % INLINE


def test_fallback_list_traces_exactly_the_inline_rays(tmp_path):
    run = run_python(SCRIPT, tmp_path, timeout=1200)
    assert run.returncode == 0, run.explain()
    for name, rows in run.result.items():
        print(name, rows)
        assert len(rows) == 2
        for r in rows:
            assert r["count"] >= 50                     # silhouettes without a visible probe
            assert r["unique"] == r["count"]             # each pixel listed once
            assert r["w_zero"]
            assert r["max_E"] > 0.0                      # the rays reached the lit scene
            assert r["max_diff"] == 0.0                  # the same rays, seeds and sums
            assert 0.0 <= r["budget_diff"] < 1e-5        # a cycle of 4 frames: the 16 strata
            assert r["skip_flags"] and r["skip_once"]    # over budget: 1 turn in 4 a pixel
            assert r["first_round_all"] and r["f12_all"]  # never in the first round nor F12
            assert r["pre_once"] and r["pre_flags"]      # integrate's skip: listed 1 turn in 4
