#include "row_table_lib.glsl"
/* Lumen GI: sampling the scene's mesh SDFs (mip 0), the GPU twin of lumen_addon.sdf.MeshSDF.sample.
 *
 * Resources (declared by the pass's GPUShaderCreateInfo, see gpu_shaders/resources.py):
 *   sampler3D  sdf_atlas        R8: every kept brick, 8^3 texels per brick cell (packing.py)
 *   isampler2D sdf_indirection  R32I: all meshes' brick tables, one linear table in rows
 *   sampler2D  sdf_objects      RGBA32F: 10 texels per instance row (packing.py), a row table
 *                               (row_table_lib.glsl)
 *   sampler2D  sdf_grid         RGBA32F: the object grid, cell -> (first entry, count, bound B)
 *                               and the flat lists of (instance, distance to the cell), nearest
 *                               first (object_grid.py has the layout)
 * Everything is read with texelFetch: trilinear filtering is done here, in float32, on the codes.
 *
 * sdf_scene visits only the instances its sample's grid cell lists (those within the margin M of
 * the cell, nearest first, stopping at the first one farther than the best value so far), so a
 * sample costs what is near it, not the whole scene; every other instance is at least the
 * cell's B >= M away, so the value is min(listed, B) (exact wherever the full loop's is below
 * M, a lower bound elsewhere: safe for sphere tracing). sdf_scene_all loops over every object.
 */

#define SDF_BRICK 8
#define SDF_BRICK_CELLS 7
#define SDF_INVALID_INSIDE -2
#define SDF_OBJECT_TEXELS 10

/* The object table's rows (a row table: its last line's unused rows are parked, a bounding
 * sphere 1e30 m away, which every loop over the objects skips). */
int sdf_object_count()
{
  return row_table_rows(textureSize(sdf_objects, 0), SDF_OBJECT_TEXELS);
}

vec4 sdf_object_texel(int obj, int texel)
{
  return texelFetch(sdf_objects, row_texel(obj, texel, SDF_OBJECT_TEXELS), 0);
}

/* Code (0..255) of sample c (0..7 per axis) of scene brick `slot`. */
float sdf_brick_code(int slot, ivec3 c)
{
  ivec3 cells = textureSize(sdf_atlas, 0) / SDF_BRICK;
  ivec3 cell = ivec3(slot % cells.x, (slot / cells.x) % cells.y, slot / (cells.x * cells.y));
  return texelFetch(sdf_atlas, cell * SDF_BRICK + c, 0).x * 255.0;
}

int sdf_indirection_fetch(int index)
{
  int width = textureSize(sdf_indirection, 0).x;
  return texelFetch(sdf_indirection, ivec2(index % width, index / width), 0).x;
}

/* Signed distance (local metres, negative inside) of object `obj` at local point p.
 * Inside the band: trilinear over the brick's codes. Invalid brick: +-band. Outside the volume:
 * the larger of the distance to the mesh bounds and the clamped value minus the gap (a lower
 * bound, safe for sphere tracing), exactly as MeshSDF.sample. */
float sdf_mesh_local(int obj, vec3 p)
{
  vec4 t4 = sdf_object_texel(obj, 4);
  vec4 t5 = sdf_object_texel(obj, 5);
  vec4 t6 = sdf_object_texel(obj, 6);
  vec4 t7 = sdf_object_texel(obj, 7);
  vec3 origin = t4.xyz;
  float h = t4.w;
  ivec3 grid = ivec3(t5.xyz + 0.5);
  float band = t5.w;
  int ind_offset = int(t6.w + 0.5);
  vec3 res = vec3(grid * SDF_BRICK_CELLS);

  vec3 g = (p - origin) / h;
  vec3 gc = clamp(g, vec3(0.0), res);
  ivec3 b = min(ivec3(floor(gc / float(SDF_BRICK_CELLS))), grid - 1);
  vec3 l = gc - vec3(b * SDF_BRICK_CELLS);
  int slot = sdf_indirection_fetch(ind_offset + b.x + grid.x * (b.y + grid.y * b.z));

  float d;
  if (slot < 0) {
    d = (slot == SDF_INVALID_INSIDE) ? -band : band;
  }
  else {
    ivec3 i0 = min(ivec3(l), ivec3(SDF_BRICK - 2));
    vec3 f = l - vec3(i0);
    float c000 = sdf_brick_code(slot, i0 + ivec3(0, 0, 0));
    float c001 = sdf_brick_code(slot, i0 + ivec3(0, 0, 1));
    float c010 = sdf_brick_code(slot, i0 + ivec3(0, 1, 0));
    float c011 = sdf_brick_code(slot, i0 + ivec3(0, 1, 1));
    float c100 = sdf_brick_code(slot, i0 + ivec3(1, 0, 0));
    float c101 = sdf_brick_code(slot, i0 + ivec3(1, 0, 1));
    float c110 = sdf_brick_code(slot, i0 + ivec3(1, 1, 0));
    float c111 = sdf_brick_code(slot, i0 + ivec3(1, 1, 1));
    float c00 = mix(c000, c001, f.z);
    float c01 = mix(c010, c011, f.z);
    float c10 = mix(c100, c101, f.z);
    float c11 = mix(c110, c111, f.z);
    float code = mix(mix(c00, c01, f.y), mix(c10, c11, f.y), f.x);
    d = (code - 127.5) / 127.5 * band;
  }
  if (any(lessThan(g, vec3(0.0))) || any(greaterThan(g, res))) {
    vec3 q = origin + gc * h;
    float gap = length(p - q);
    float to_box = length(max(max(t6.xyz - p, p - t7.xyz), vec3(0.0)));
    d = max(to_box, d - gap);
  }
  return d;
}

vec3 sdf_world_to_local(int obj, vec3 pw)
{
  vec4 pw4 = vec4(pw, 1.0);
  return vec3(dot(sdf_object_texel(obj, 0), pw4),
              dot(sdf_object_texel(obj, 1), pw4),
              dot(sdf_object_texel(obj, 2), pw4));
}

/* Instances visited by this invocation's sdf_scene calls: sphere tests, full evaluations
 * (tests/gpu/test_object_grid.py reads them; unused otherwise, so the compiler drops them). */
int sdf_tests = 0;
int sdf_visits = 0;

/* True while a light's or the sky's visibility cone samples the scene (light_lib.glsl): then
 * texel 9 y of an instance is the share of light its shadow lets pass (scene_state.py
 * shadow_pass), and an instance that lets some pass is not in the distance: 1 (Object >
 * Visibility > Ray Visibility > Shadow off) as Cycles' shadow rays pass it; between 0 and 1 a
 * cut-out's holes (leaves, a fence): with LIGHT_CUT_OUTS (compute.VARIANTS: a scene that has
 * one) the nearest such instance is sdf_part_d, sdf_part_obj instead (the caller resets them),
 * which the cone lets through by that share where it crosses its shell. Every other use of the
 * field (GI rays, the global SDF, the camera's traces) sees every instance. */
bool sdf_shadow_rays = false;
#ifdef LIGHT_CUT_OUTS
float sdf_part_d = 1e30;
int sdf_part_obj = -1;
#endif

/* One instance's part of a scene minimum. Its value is the larger of its sample and a lower
 * bound of its true distance where that bound is positive (outside the mesh bounds; inside them
 * the sample alone, negative within a solid): the distance to its bounding sphere (texel 8,
 * around the mesh bounds grown by half a voxel), then to its local bounds box less half a voxel
 * (a two-sided mesh stores distance minus half a voxel). Inside the SDF volume a sample far from
 * the surface reads the clamped band, less than the bounds' distance; with the bound in the
 * value, an instance whose sphere, then whose box, is no nearer than `best` is skipped exactly
 * (its value is at least that far) before its bricks are read. Bounds as tight as the mesh: a
 * sphere around the whole SDF volume (band padding: 1.5 m around a 0.25 m icosphere at 8
 * voxels/m) let every neighbour through. global_sdf_ref.scene_sdf is the numpy twin. */
void sdf_visit(int i, vec3 pw, inout float best, inout float voxel_world, inout int nearest)
{
  sdf_tests++;
  vec4 sphere = sdf_object_texel(i, 8);
  float lb = length(pw - sphere.xyz) - sphere.w;
  if (lb > 0.0 && lb >= best) {
    return;
  }
  vec3 p = sdf_world_to_local(i, pw);
  vec4 t4 = sdf_object_texel(i, 4);
  vec4 t7 = sdf_object_texel(i, 7);
  float to_box = length(max(max(sdf_object_texel(i, 6).xyz - p, p - t7.xyz), vec3(0.0)));
  lb = max(lb, (to_box - 0.5 * t4.w) * t7.w);
  if (lb > 0.0 && lb >= best) {
    return;
  }
  sdf_visits++;
  float d = sdf_mesh_local(i, p) * t7.w;
  if (lb > 0.0) {
    d = max(d, lb);
  }
  /* the flag read only where the instance would be nearest (a few times a sample; before the
   * field, at every visit, the viewport's direct light took 1.09x) */
#ifdef LIGHT_CUT_OUTS
  if (d < best) {
    float share = sdf_shadow_rays ? sdf_object_texel(i, 9).y : 0.0;
    if (share <= 0.0) {
      best = d;
      voxel_world = t4.w * t7.w;
      nearest = i;
    }
    else if (share < 1.0 && d < sdf_part_d) {
      sdf_part_d = d;
      sdf_part_obj = i;
    }
  }
#else
  if (d < best && !(sdf_shadow_rays && sdf_object_texel(i, 9).y > 0.0)) {
    best = d;
    voxel_world = t4.w * t7.w;
    nearest = i;
  }
#endif
}

/* Scene distance over every object: the minimum of their values. voxel_world: voxel of the
 * nearest object; nearest: its index (-1 with no objects, distance 1e30). An object whose
 * bounding sphere (texel 8) is farther than the best distance so far is skipped: its value is
 * at least that far. O(objects): sdf_scene's fallback for a cell that lists too many. */
float sdf_scene_all(vec3 pw, out float voxel_world, out int nearest)
{
  float best = 1e30;
  voxel_world = 1.0;
  nearest = -1;
  int n = sdf_object_count();
  for (int i = 0; i < n; i++) {
    sdf_visit(i, pw, best, voxel_world, nearest);
  }
  return best;
}

vec4 sdf_grid_texel(int i)
{
  int width = textureSize(sdf_grid, 0).x;
  return texelFetch(sdf_grid, ivec2(i % width, i / width), 0);
}

/* The object grid's part of sdf_scene: the minimum over the instances listed in pw's cell (1e30
 * with none; voxel_world and nearest of that instance, else the scene's smallest voxel and -1),
 * and `bound`, a lower bound of every unlisted instance's value: sqrt(|pw - q|^2 + B^2), q = pw
 * clamped into the grid box (a point outside the grid uses the cell of q: every instance lies in
 * the box, so an unlisted one is at least that far from pw, projection onto a convex set).
 * A cell that lists more than the cap (count -1) walks every object (bound 1e30): returns false. */
bool sdf_scene_grid(vec3 pw, out float best, out float voxel_world, out int nearest,
                    out float bound)
{
  vec4 g0 = sdf_grid_texel(0);
  vec4 g1 = sdf_grid_texel(1);
  ivec3 dims = ivec3(g1.xyz + 0.5);
  vec3 lo = g0.xyz;
  vec3 q = clamp(pw, lo, lo + vec3(dims) * g0.w);
  ivec3 c = clamp(ivec3(floor((q - lo) / g0.w)), ivec3(0), dims - 1);
  vec4 cell = sdf_grid_texel(3 + c.x + dims.x * (c.y + dims.y * c.z));
  int count = int(round(cell.y));
  bool listed = count >= 0;
  best = 1e30;
  voxel_world = listed ? sdf_grid_texel(2).y : 1.0;
  nearest = -1;
  bound = (listed && cell.z < 1e29) ? length(vec2(length(pw - q), cell.z)) : 1e30;
  /* one loop for both cases (an overflowing cell walks every object in index order, as
   * sdf_scene_all): every caller inlines this, and a second loop doubled the shaders' size */
  int n = listed ? count : sdf_object_count();
  int first = int(cell.x + 0.5);
  int list = int(g1.w + 0.5);
  for (int k = 0; k < n; k++) {
    int i = k;
    if (listed) {
      int e = first + k;
      vec4 pair = sdf_grid_texel(list + (e >> 1));
      vec2 entry = (e & 1) == 0 ? pair.xy : pair.zw;
      /* nearest first: this instance and every later one are at least this far; not at 0 (an
       * instance over the cell): inside a solid best < 0, and an overlapping one can be deeper */
      if (entry.y >= best && entry.y > 0.0) {
        break;
      }
      i = int(entry.x + 0.5);
    }
    sdf_visit(i, pw, best, voxel_world, nearest);
  }
  return listed;
}

/* The ray's span (t_enter, t_exit) through the object grid's box (every instance's world AABB,
 * grown by half a voxel, lies in it) grown by `margin` on every side; t_enter > t_exit: it
 * misses the box. Nothing lies outside the box, so a trace may stop where the ray leaves it.
 * exit_cosine: |dir| along the normal of the face the ray leaves through (past the exit, the
 * distance to the box grows at least this fast). */
vec2 sdf_scene_box_span(vec3 o, vec3 dir, float margin, out float exit_cosine)
{
  vec4 g0 = sdf_grid_texel(0);
  vec3 lo = g0.xyz - margin;
  vec3 hi = g0.xyz + floor(sdf_grid_texel(1).xyz + 0.5) * g0.w + margin;
  /* a zero component as 1e-30: a huge finite slope orders the slabs as +-inf would, and a ray
   * starting on a face plane gives 0 there, not 0 * inf = NaN */
  vec3 inv = 1.0 / mix(dir, vec3(1e-30), equal(dir, vec3(0.0)));
  vec3 a = (lo - o) * inv;
  vec3 b = (hi - o) * inv;
  vec3 near = min(a, b);
  vec3 far = max(a, b);
  vec3 c = abs(dir);
  exit_cosine = far.x <= far.y && far.x <= far.z ? c.x : (far.y <= far.z ? c.y : c.z);
  return vec2(max(max(near.x, near.y), near.z), min(min(far.x, far.y), far.z));
}

vec2 sdf_scene_box_span(vec3 o, vec3 dir, float margin)
{
  float exit_cosine;
  return sdf_scene_box_span(o, dir, margin, exit_cosine);
}

/* Scene distance through the object grid, with sdf_scene_all's contract (voxel_world and nearest
 * of the nearest listed instance; with none listed, the scene's smallest voxel and -1): the
 * minimum of the listed instances and the unlisted ones' bound. Equal to sdf_scene_all wherever
 * that is below the grid's margin M, a lower bound of it elsewhere (safe for sphere tracing). */
float sdf_scene(vec3 pw, out float voxel_world, out int nearest)
{
  float best, bound;
  sdf_scene_grid(pw, best, voxel_world, nearest, bound);
  return min(best, bound);
}

/* sdf_scene, but equal to sdf_scene_all wherever that is below `reach` (the global SDF stores
 * values up to its band, 4 of its voxels, which can be far beyond M): where the unlisted
 * instances' bound would cut the value below reach, the full loop. */
float sdf_scene_reach(vec3 pw, float reach, out float voxel_world, out int nearest)
{
  float best, bound;
  if (sdf_scene_grid(pw, best, voxel_world, nearest, bound) && bound < min(best, reach)) {
    return sdf_scene_all(pw, voxel_world, nearest);
  }
  return min(best, bound);
}
