#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "global_sdf_lib.glsl"
#include "voxel_lighting_layout_lib.glsl"
#include "voxel_lighting_lib.glsl"
/* Lumen GI: the voxel lighting tiles' object lists, searched by gi_trace at a global-SDF hit
 * (split from voxel_lighting_lib.glsl, whose lookup needs no mesh SDFs). */
int vl_tile_objs[VL_TILE_OBJECTS];
int vl_tile_count;

/* Load the object list of the tile holding world point p in `level` (step 1 of the update:
 * the objects whose bounding spheres come within 1.5 voxels of the tile); false without voxel
 * lighting, or when the list is full (more objects may come that near: every object is searched
 * then, as without voxel lighting). */
bool vl_load_tile(int level, vec3 p)
{
  vl_tile_count = 0;
  if (level < 0 || !vl_enabled()) {
    return false;
  }
  int n = textureSize(gsdf_level0, 0).x;
  vec4 info = gsdf_origin(level);
  ivec3 rel = clamp(ivec3(floor(p / info.w)) - ivec3(round(info.xyz)), ivec3(0), ivec3(n - 1));
  ivec2 at = vl_tile_texel(level, rel / VL_TILE, n);
  for (int j = 0; j < VL_TILE_OBJECTS; j++) {
    float fi = texelFetch(vl_tiles, at + ivec2(j, 0), 0).x;
    if (fi < -0.5) {
      break;
    }
    vl_tile_objs[j] = int(fi + 0.5);
    vl_tile_count++;
  }
  return vl_tile_count < VL_TILE_OBJECTS;
}

/* sdf_scene over the loaded tile's objects only. */
float vl_tile_scene(vec3 pw, out float voxel_world, out int nearest)
{
  float best = 1e30;
  voxel_world = 1.0;
  nearest = -1;
  for (int j = 0; j < vl_tile_count; j++) {
    sdf_visit(vl_tile_objs[j], pw, best, voxel_world, nearest);
  }
  return best;
}

/* gi_trace_mesh (sdf_ray_lib.glsl: the thin-wall rule, a start inside a shell hits at once)
 * through the loaded tile's objects only. */
bool vl_trace_tile(vec3 o, vec3 dir, float t0, float t1, out float t, out int obj)
{
  t = t0;
  obj = -1;
  for (int i = 0; i < GI_MESH_STEPS; i++) {
    float h;
    int nearest;
    float d = vl_tile_scene(o + t * dir, h, nearest);
    if (d <= GI_HIT_VOXELS * h) {
      obj = nearest;
      return true;
    }
    t += max(d, 0.1 * h);
    if (t > t1) {
      break;
    }
  }
  return false;
}
