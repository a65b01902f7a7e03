"""The global SDF: 4 clipmap levels around the camera, built on the GPU from the mesh SDFs.

Needs a GPU context (RenderEngine.render / view_draw with bl_use_gpu_context). Level k is an
N^3 R16F (or R32F) 3D texture of voxel size base * 2^k whose first world cell is
floor(camera / voxel) - N/2 (snapped to the level's own grid; see global_sdf_ref.py for the
layout). Each texel stores min(sdf_scene(centre), band), band = BAND_VOXELS voxels of that level:
exact inside the band, a conservative bound beyond it.

`update(camera_pos, frame, objects_changed)`: level k is due on frames that are multiples of 2^k;
a due level is scrolled when its snapped origin moved (only the cells new to the level are
evaluated: toroidal texels) and, when objects moved since its last update, refreshes only the
cells within its band of their old and new world bounds (SceneResources.boxes_since: a value
clamped to the band cannot change farther away; the result is bit-identical to a rebuild). It
is rebuilt whole when the change is unknown (a new table size, a change the table does not
show) or spans more than MAX_PENDING_BOXES boxes. Why: one sphere moved among 1,000 rebuilt
all four levels, 0.3 s each for the coarse ones (their band reaches past the object grid's
margin, so their cells loop over every object); their boxes take 31-38 ms. A box's cells that
fall back from the object grid visit only the instances whose bounding spheres come within the
band of their block of 4^3 cells (`_candidates`), not every object: the same texels.
A level that was never built is built at once. `glsl/global_sdf_lib.glsl` samples the levels
(`global_sdf_sample`) and traces rays (`trace_hybrid`: mesh SDFs for t < 1.8 m, global beyond).
"""
from __future__ import annotations

import time

import gpu
import numpy as np

from . import compute
from .global_sdf_ref import BAND_VOXELS, LEVELS, level_origin, level_voxel, merge_boxes
from .object_grid import instance_bounds
from .resources import SceneResources, float_buffer, glsl, read_texture

GROUP = 4
MAX_PENDING_BOXES = 32    # changed boxes a level refreshes one by one; more: the whole level
UBO_SLOT = 0   # GlobalSDFParams' binding; no other pass library declares a uniform block
PARAMS_TYPEDEF = """
struct GlobalSDFParams {
  vec4 origin[4]; /* xyz: the level's first world cell (integers), w: its voxel size (m) */
  vec4 band;      /* x: values are clamped to min(d, band.x * voxel) per level; y: half the
                     largest mesh voxel in world metres (the thin-wall margin of gi_trace) */
};
"""
BYTES = {"R16F": 2, "R32F": 4}
LIST_WIDTH = 1024         # columns of a box refresh's candidate list texture
SUB_CELLS = 4             # a box refresh's candidate lists: one per block of 4^3 cells
_SHADERS = {}


def _build_shader(fmt: str):
    """The build shader for a level texture of format fmt (the image format must match it)."""
    key = "build_" + fmt
    if key not in _SHADERS:
        info = compute.new_info((GROUP, GROUP, GROUP))
        SceneResources.declare(info, 0)
        info.image(0, fmt, 'FLOAT_3D', 'gsdf_out', qualifiers={'WRITE'})
        info.push_constant('VEC4', 'build_origin')
        info.push_constant('VEC4', 'build_prev')
        info.push_constant('FLOAT', 'build_band')
        info.push_constant('VEC4', 'build_box')
        info.push_constant('VEC4', 'build_box_end')
        info.push_constant('INT', 'build_list_sub')
        info.sampler(4, 'FLOAT_2D', 'build_list')
        imod = ("ivec3 gsdf_imod(ivec3 a, int n)\n{\n"
                "  return a - n * ivec3(floor(vec3(a) / float(n)));\n}\n")
        _SHADERS[key] = compute.create(
            info, imod + glsl("global_sdf_build.comp.glsl"))
    return _SHADERS[key]


def _flatten_shader():
    if "flatten" not in _SHADERS:
        info = compute.new_info((8, 8, 1))
        info.sampler(0, 'FLOAT_3D', 'src')
        info.image(0, 'R32F', 'FLOAT_2D', 'dst', qualifiers={'WRITE'})
        _SHADERS["flatten"] = compute.create(
            info,
            "void main() {\n"
            "  ivec2 p = ivec2(gl_GlobalInvocationID.xy);\n"
            "  int n = textureSize(src, 0).x;\n"
            "  if (p.x >= n || p.y >= n * n) { return; }\n"
            "  imageStore(dst, p, vec4(texelFetch(src, ivec3(p.x, p.y % n, p.y / n), 0).x));\n"
            "}\n")
    return _SHADERS["flatten"]


class GlobalSDF:
    """4 clipmap levels of the scene SDF around the camera (see the module docstring)."""

    def __init__(self, resources: SceneResources, n: int = 64, base_voxel: float = 0.1,
                 fmt: str = 'R16F', levels: int = LEVELS, band_voxels: float = BAND_VOXELS):
        if fmt not in BYTES:
            raise ValueError(f"format {fmt!r}: use one of {sorted(BYTES)}")
        if levels != LEVELS:
            raise ValueError(f"global_sdf_lib.glsl samples exactly {LEVELS} levels")
        self.resources = resources
        self.n, self.base_voxel, self.format, self.band_voxels = int(n), float(base_voxel), fmt, float(band_voxels)
        self.voxels = [level_voxel(base_voxel, k) for k in range(levels)]
        self.textures = [gpu.types.GPUTexture((n, n, n), format=fmt) for _ in range(levels)]
        self.origins = [None] * levels           # first world cell of each level, None: never built
        self.dirty = [True] * levels             # objects changed since the level's last build
        self.pending = [[] for _ in range(levels)]   # world boxes (lo, hi) to refresh when due
        self.version = getattr(resources, "objects_version", 0)   # object table last seen
        self.last_update = [None] * levels       # frame of the last build/scroll
        self.log = []                            # (frame, level, kind (update's), seconds)
        self._ubo, self._ubo_data = None, None   # GlobalSDFParams of the bound origins
        self._spheres = None                     # (object rows, their bounding spheres)
        self.candidates = []        # (level, longest block list, objects) per box refresh

    # --- building --------------------------------------------------------------------------
    def set_resources(self, resources: SceneResources):
        """New mesh-SDF textures (objects moved / re-baked): every level is rebuilt when due."""
        self.resources = resources
        self.dirty = [True] * len(self.dirty)
        self.version = getattr(resources, "objects_version", 0)

    def _candidates(self, level: int, box):
        """Per block of SUB_CELLS^3 cells of `box` (x fastest), the instances whose bounding
        spheres come within the level's band of one of its cell centres: the only ones whose
        values a refresh there can store (sdf_visit never returns less than the distance to an
        instance's bounding sphere; the band clamps the rest). Returns an R32F texture of
        LIST_WIDTH columns, flat: each block's (first entry, count), then the entries (object
        rows, ascending), and the longest block's count. Why: the coarse levels' band reaches past
        the object grid's margin, so a refresh's cells in open space fell back to every object
        (42 ms of a redraw after one of 1,000 spheres moved; one list for the whole box still
        held 874 of them at the coarsest level)."""
        objects = self.resources.packed.objects
        if self._spheres is None or self._spheres[0] is not objects:
            valid, centre, radius, _, _, _ = instance_bounds(objects)
            self._spheres = (objects, valid, centre, radius)
        _, valid, centre, radius = self._spheres
        v = self.voxels[level]
        first, end = np.asarray(box[0], np.int64), np.asarray(box[1], np.int64)
        blocks = -(-(end - first) // SUB_CELLS)
        ijk = np.stack(np.meshgrid(*[np.arange(b) for b in blocks], indexing="ij"), -1)
        ijk = ijk.transpose(2, 1, 0, 3).reshape(-1, 3)                   # x fastest
        a = first + ijk * SUB_CELLS
        b = np.minimum(a + SUB_CELLS, end)
        lo, hi = (a + 0.5) * v, (b - 0.5) * v
        gap = np.linalg.norm(np.maximum(np.maximum(lo[:, None] - centre[None],
                                                   centre[None] - hi[:, None]), 0.0), axis=2)
        near = valid[None] & (gap - radius[None] < self.band_voxels * v)
        counts = near.sum(axis=1)
        blk, rows = np.nonzero(near)                  # by block, rows ascending within
        header = np.stack([2 * len(counts) + np.cumsum(counts) - counts, counts], 1)
        flat = np.concatenate([header.reshape(-1), rows]).astype(np.float32)
        tex = np.zeros(-(-len(flat) // LIST_WIDTH) * LIST_WIDTH, np.float32)
        tex[:len(flat)] = flat
        return gpu.types.GPUTexture((LIST_WIDTH, len(tex) // LIST_WIDTH), format='R32F',
                                    data=float_buffer(tex.reshape(-1, LIST_WIDTH))), \
            int(counts.max(initial=0))

    def _dispatch(self, level: int, origin, prev, box=None):
        """Build (prev None), scroll (prev: the last origin) or, with box = (first cell, end
        cell), refresh the level's cells in that box (they must lie in the level; where the
        object grid cannot give a value, only the box's candidate instances are visited)."""
        sh = _build_shader(self.format)
        self.resources.bind(sh)
        if box is None:
            listed, sub = gpu.types.GPUTexture((1, 1), format='R32F'), -1
        else:
            listed, longest = self._candidates(level, box)
            sub = SUB_CELLS
            self.candidates.append((level, longest, len(self.resources.packed.objects)))
        sh.uniform_sampler('build_list', listed)
        sh.uniform_int('build_list_sub', sub)
        sh.image('gsdf_out', self.textures[level])
        v = self.voxels[level]
        sh.uniform_float('build_origin', (*map(float, origin), v))
        sh.uniform_float('build_prev', (*map(float, prev), 1.0) if prev is not None else (0.0, 0.0, 0.0, 0.0))
        sh.uniform_float('build_band', self.band_voxels * v)
        sh.uniform_float('build_box', (*map(float, box[0]), 1.0) if box is not None else (0.0,) * 4)
        sh.uniform_float('build_box_end', (*map(float, box[1]), 0.0) if box is not None else (0.0,) * 4)
        if box is None:
            g = -(-self.n // GROUP)
            compute.run(sh, g, g, g)
        else:
            ext = [-(-(int(b) - int(a)) // GROUP) for a, b in zip(*box)]
            compute.run(sh, *ext)

    def _level_box(self, level: int, origin, lo, hi):
        """The cells of level `level` (first cell `origin`) whose values a change within the
        world box [lo, hi] can alter: those whose centres lie within the level's band of it
        (beyond, every value is clamped to the band before and after), clipped to the level;
        None when none."""
        v = self.voxels[level]
        reach = self.band_voxels * v + v
        first = np.maximum(np.floor((np.asarray(lo) - reach) / v), origin).astype(np.int64)
        end = np.minimum(np.floor((np.asarray(hi) + reach) / v) + 1, np.asarray(origin) + self.n)
        end = end.astype(np.int64)
        return (tuple(first), tuple(end)) if np.all(end > first) else None

    def _note_objects_changed(self):
        """Objects changed: each level gets the resources' changed boxes since the version
        last seen to refresh when due, or a whole rebuild where they are unknown, none (a
        change the table does not show) or too many."""
        since = getattr(self.resources, "boxes_since", None)
        boxes = since(self.version) if since is not None else None
        self.version = getattr(self.resources, "objects_version", 0)
        for k in range(len(self.dirty)):
            # no box recorded (a change the object table does not show): everything, as before
            if not boxes or len(self.pending[k]) + len(boxes) > MAX_PENDING_BOXES:
                self.dirty[k], self.pending[k] = True, []
            elif not self.dirty[k]:
                self.pending[k] += boxes

    def update(self, camera_pos, frame: int, objects_changed: bool = False) -> list:
        """Refresh the levels due this frame; returns [(level, kind)] done, kind 'build',
        'scroll', 'boxes' (only the cells near moved objects) or 'scroll+boxes'."""
        if objects_changed:
            self._note_objects_changed()
        done = []
        for k, v in enumerate(self.voxels):
            first = self.origins[k] is None
            if not first and int(frame) % (1 << k):
                continue                                  # not this level's frame
            origin = level_origin(camera_pos, v, self.n)
            moved = origin != self.origins[k]
            if not (first or self.dirty[k] or moved or self.pending[k]):
                continue
            t0 = time.perf_counter()
            full = first or self.dirty[k] or max(abs(a - b) for a, b in zip(origin, self.origins[k])) >= self.n
            if full or moved:
                self._dispatch(k, origin, None if full else self.origins[k])
            kind = "build" if full else ("scroll" if moved else "boxes")
            if not full:            # the cells near what moved (after the scroll: in the new box)
                boxes = [self._level_box(k, origin, lo, hi) for lo, hi in self.pending[k]]
                for box in merge_boxes([b for b in boxes if b is not None]):
                    self._dispatch(k, origin, None, box)
                if self.pending[k] and moved:
                    kind = "scroll+boxes"
            self.origins[k], self.dirty[k], self.last_update[k] = origin, False, int(frame)
            self.pending[k] = []
            self.log.append((int(frame), k, kind, time.perf_counter() - t0))
            done.append((k, kind))
        return done

    def build_all(self, camera_pos):
        """Build every level now around camera_pos (whatever the frame)."""
        self.dirty = [True] * len(self.dirty)
        self.origins = [None] * len(self.origins)
        return self.update(camera_pos, 0)

    # --- reading ---------------------------------------------------------------------------
    def read_level(self, level: int) -> np.ndarray:
        """float32 [n, n, n] ([z, y, x]) texels of one level (waits for the GPU).

        GPUTexture.read() of a 3D texture returns its first slice only (Blender 5.0.1 sizes the
        buffer width * height), so the level is first copied into an n x n^2 2D R32F texture."""
        n = self.n
        flat = gpu.types.GPUTexture((n, n * n), format='R32F')
        sh = _flatten_shader()
        sh.uniform_sampler('src', self.textures[level])
        sh.image('dst', flat)
        compute.run(sh, -(-n // 8), -(-n * n // 8), 1)
        return read_texture(flat, (n, n, n))

    def stats(self) -> dict:
        """GPU bytes per level from the allocated textures' sizes and format."""
        out = {}
        for k, tex in enumerate(self.textures):
            # GPUTexture exposes width, height and format; the depth is the n it was created with
            out[f"level{k}"] = int(tex.width * tex.height * self.n * BYTES[tex.format])
        out["total"] = sum(out.values())
        return out

    # --- sampling from other passes ----------------------------------------------------------
    @staticmethod
    def declare(info, first_slot: int) -> int:
        """Declare global_sdf_lib.glsl's samplers and its uniform block; returns the next free
        sampler slot. The level origins live in a uniform block, not push constants: 80 bytes
        of them would leave a pass too little of Vulkan's guaranteed 128 push-constant bytes."""
        for k in range(LEVELS):
            info.sampler(first_slot + k, 'FLOAT_3D', f'gsdf_level{k}')
        info.typedef_source(PARAMS_TYPEDEF)
        info.uniform_buf(UBO_SLOT, "GlobalSDFParams", "gsdf")
        return first_slot + LEVELS

    def params(self) -> np.ndarray:
        """float32 [LEVELS + 1, 4]: GlobalSDFParams in std140 (origin[k] = cell xyz, voxel; band,
        thin-wall margin). The margin is computed here once per bind, not per ray on the GPU,
        where it was a loop over every object."""
        rows = [(*map(float, self.origins[k]), self.voxels[k]) for k in range(LEVELS)]
        return np.array(rows + [(self.band_voxels, self.thin_margin(), 0.0, 0.0)], np.float32)

    def thin_margin(self) -> float:
        """Half the largest world voxel of the mesh SDFs (object table texels 4.w x 7.w, the same
        float32 product the shaders used to take per ray)."""
        objects = np.asarray(self.resources.packed.objects, np.float32)
        if not len(objects):
            return 0.0
        return float(0.5 * np.max(objects[:, 4, 3] * objects[:, 7, 3]))

    def bind(self, shader):
        if any(o is None for o in self.origins):
            raise RuntimeError("GlobalSDF.bind before every level was built (call update first)")
        for k, tex in enumerate(self.textures):
            shader.uniform_sampler(f'gsdf_level{k}', tex)
        params = self.params()
        if self._ubo is None or not np.array_equal(params, self._ubo_data):
            # a new block when the origins move (at most once a frame), not one per pass
            self._ubo = gpu.types.GPUUniformBuf(float_buffer(params))
            self._ubo_data = params
        shader.uniform_block("gsdf", self._ubo)


# --- the hybrid trace pass (tests and the engine's future global trace) -----------------------
TRACE_MAIN = """
void main()
{
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(trace_out);
  if (px.x >= size.x || px.y >= size.y) {
    return;
  }
  vec3 ro, rd;
  camera_ray(px, size, ro, rd);
  int steps, global_steps;
  float hit = trace_hybrid(ro, rd, t_max, max_steps, steps, global_steps);
  imageStore(trace_out, px, vec4(hit, float(steps), float(global_steps), 0.0));
}
"""


def hybrid_trace_shader():
    if "trace" not in _SHADERS:
        info = compute.new_info((8, 8, 1))
        slot = SceneResources.declare(info, 0)
        GlobalSDF.declare(info, slot)
        info.image(0, 'RGBA32F', 'FLOAT_2D', 'trace_out', qualifiers={'WRITE'})
        info.push_constant('MAT4', 'inv_view_proj')
        info.push_constant('FLOAT', 't_max')
        info.push_constant('INT', 'max_steps')
        _SHADERS["trace"] = compute.create(
            info, glsl(("global_sdf_trace_lib.glsl", "camera_lib.glsl")) + "\n" + TRACE_MAIN)
    return _SHADERS["trace"]


def trace_hybrid(gsdf: GlobalSDF, inv_view_proj, width: int, height: int, t_max: float,
                 max_steps: int = 512) -> dict:
    """One trace_hybrid ray per pixel (rays as sdf_trace / reference.camera_rays).
    Returns {'hit' (-1 miss), 'steps', 'global_steps' [h, w], 'seconds'}."""
    import mathutils

    sh = hybrid_trace_shader()
    t0 = time.perf_counter()
    out = gpu.types.GPUTexture((width, height), format='RGBA32F')
    gsdf.resources.bind(sh)
    gsdf.bind(sh)
    sh.image('trace_out', out)
    sh.uniform_float('inv_view_proj', mathutils.Matrix(np.asarray(inv_view_proj, np.float64).tolist()))
    sh.uniform_float('t_max', float(t_max))
    sh.uniform_int('max_steps', int(max_steps))
    compute.run(sh, -(-width // 8), -(-height // 8), 1)
    data = read_texture(out, (height, width, 4))
    return {"hit": data[..., 0].copy(), "steps": data[..., 1].astype(np.int32),
            "global_steps": data[..., 2].astype(np.int32), "seconds": time.perf_counter() - t0}


SAMPLE_MAIN = """
void main()
{
  int i = int(gl_GlobalInvocationID.x);
  int count = textureSize(points, 0).x;
  if (i >= count) {
    return;
  }
  int level;
  float voxel;
  float d = global_sdf_sample(texelFetch(points, ivec2(i, 0), 0).xyz, level, voxel);
  imageStore(sample_out, ivec2(i, 0), vec4(d, float(level), voxel, 0.0));
}
"""


def sample_points(gsdf: GlobalSDF, points) -> dict:
    """global_sdf_sample at world points (float [P, 3]): {'d', 'level' (-1 outside), 'voxel'}."""
    if "sample" not in _SHADERS:
        info = compute.new_info((64, 1, 1))
        info.sampler(0, 'FLOAT_2D', 'points')
        GlobalSDF.declare(info, 1)
        info.image(0, 'RGBA32F', 'FLOAT_2D', 'sample_out', qualifiers={'WRITE'})
        _SHADERS["sample"] = compute.create(info, glsl("global_sdf_lib.glsl") + "\n" + SAMPLE_MAIN)
    sh = _SHADERS["sample"]

    p = np.asarray(points, np.float32).reshape(-1, 3)
    count = len(p)
    rgba = np.zeros((count, 4), np.float32)
    rgba[:, :3] = p
    src = gpu.types.GPUTexture((count, 1), format='RGBA32F', data=float_buffer(rgba))
    out = gpu.types.GPUTexture((count, 1), format='RGBA32F')
    sh.uniform_sampler('points', src)
    gsdf.bind(sh)
    sh.image('sample_out', out)
    compute.run(sh, -(-count // 64), 1, 1)
    data = read_texture(out, (count, 4))
    return {"d": data[:, 0].copy(), "level": data[:, 1].astype(np.int32), "voxel": data[:, 2].copy()}
