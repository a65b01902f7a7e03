#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "global_sdf_lib.glsl"
#include "surface_cache_lib.glsl"
#include "voxel_lighting_layout_lib.glsl"
/* Voxel lighting, step 2: the 6 faces of the voxels step 1 listed (near a surface, not inside a
 * solid), from short mesh-SDF rays and the surface cache (what a face holds:
 * voxel_lighting_layout_lib.glsl). The lecture's "build voxel faces by short ray cast" shoots
 * from centre - axis x radius to centre + axis x radius; here each ray starts at the centre and
 * goes VL_REACH voxels ahead: a ray from behind a centre that met a surface before reaching it
 * came from across that surface, and through a wall thinner than a voxel brought the light of
 * its other side into the room (bench/quality.py's thin room). One invocation per list entry
 * (thread (x, y): entry x + VL_LIST_WIDTH y; -1: past the last, nothing to do). Per face, a ray
 * through the voxel's tile's objects only (step 1's list, with sdf_scene's bounding-sphere skip and
 * gi_trace_mesh's thin-wall rule), and at its hit the surface cache's final light
 * (sc_sample_local: the object's own cards, without the thin-wall texel guard, which would loop
 * over every object).
 * The hits depend on the geometry only: with vl_trace = 1 each face's ray is traced and its hit
 * stored in vl_hits (two texels per face: object-local point and object + 1 (0: no surface),
 * local normal and distance in voxels); with vl_trace = 0 (the same list: the level's clipmap
 * and the objects unchanged since) the stored hits are read and only the surface cache is
 * sampled again, so the light of a new bounce costs no rays (voxel_lighting.py).
 * Push constants: vl_level, vl_trace. Samplers: vl_tiles, vl_list (step 1). Output out_image
 * (RGBA16F); vl_hits (RGBA32F, read-write: entry (x, y) of the list, face f at texels
 * (12 x + 2 f + c, y)).
 */
#define VL_STEPS 32

int vl_objs[VL_TILE_OBJECTS];
int vl_count;

/* sdf_scene over the tile's objects only. */
float vl_scene(vec3 pw, out float voxel_world, out int nearest)
{
  float best = 1e30;
  voxel_world = 1.0;
  nearest = -1;
  for (int j = 0; j < vl_count; j++) {
    sdf_visit(vl_objs[j], pw, best, voxel_world, nearest);
  }
  return best;
}

/* First surface along unit a from s within len (gi_trace_mesh's rule: hit within half a voxel,
 * a start inside a surface's shell too). */
bool vl_face_ray(vec3 s, vec3 a, float len, out vec3 q, out int obj)
{
  q = s;
  obj = -1;
  float t = 0.0;
  for (int i = 0; i < VL_STEPS; i++) {
    float h;
    int nearest;
    float d = vl_scene(s + t * a, h, nearest);
    if (i == 0 && d < -0.25 * h) {
      /* starts inside a solid (mesh SDFs are clamped at about -half a voxel inside: a quarter
       * tells inside from on-the-surface; from the middle of a slab the gradient would pick
       * either side, the outside's light then leaking in) */
      return false;
    }
    if (d <= GI_HIT_VOXELS * h) {
      q = s + t * a;
      obj = nearest;
      return true;
    }
    t += max(d, 0.1 * h);
    if (t > len) {
      break;
    }
  }
  return false;
}

void main()
{
  ivec2 id = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = textureSize(vl_list, 0);
  if (id.x >= size.x || id.y >= size.y) {
    return;
  }
  float entry = texelFetch(vl_list, id, 0).x;
  if (entry < -0.5) {
    return;
  }
  int n = textureSize(gsdf_level0, 0).x;
  int e = int(entry + 0.5);
  ivec3 t = ivec3(e % n, (e / n) % n, e / (n * n));
  vec4 info = gsdf_origin(vl_level);
  float v = info.w;
  ivec3 o = ivec3(round(info.xyz));
  ivec3 rel = gsdf_imod(t - o, n);               /* the voxel's cell is o + rel */
  vec3 centre = (vec3(o + rel) + 0.5) * v;

  if (vl_trace == 0) {
    for (int f = 0; f < VL_FACES; f++) {
      vec4 a = imageLoad(vl_hits, ivec2(12 * id.x + 2 * f, id.y));
      vec4 face = vec4(0.0);
      if (a.w > 0.5) {
        vec4 b = imageLoad(vl_hits, ivec2(12 * id.x + 2 * f + 1, id.y));
        int obj = int(a.w - 0.5);
        float h = sdf_object_texel(obj, 4).w;
        float w;
        vec3 L = sc_sample_local(obj, a.xyz, b.xyz, h, inverse(sc_object_w2l(obj)), 0.0, w);
        face = w > 0.0 ? vec4(L, vl_face_code(b.w, true)) : vec4(0.0, 0.0, 0.0, vl_face_code(b.w, false));
      }
      imageStore(out_image, vl_texel(vl_level, f, t, n), face);
    }
    return;
  }
  vl_count = 0;
  ivec2 at = vl_tile_texel(vl_level, rel / VL_TILE, n);
  for (int j = 0; j < VL_TILE_OBJECTS; j++) {
    float fi = texelFetch(vl_tiles, at + ivec2(j, 0), 0).x;
    if (fi < -0.5) {
      break;
    }
    vl_objs[j] = int(fi + 0.5);
    vl_count++;
  }
  for (int f = 0; f < VL_FACES; f++) {
    vec4 face = vec4(0.0);
    vec4 hit_a = vec4(0.0);
    vec4 hit_b = vec4(0.0);
    vec3 q;
    int obj;
    if (vl_face_ray(centre, SC_AXES[f], VL_REACH * v, q, obj)) {
      vec3 pl = sdf_world_to_local(obj, q);
      float h = sdf_object_texel(obj, 4).w;
      vec3 nl = sdf_mesh_normal_local(obj, pl, 0.5 * h);
      float w;
      vec3 L = sc_sample_local(obj, pl, nl, h, inverse(sc_object_w2l(obj)), 0.0, w);
      float s = dot(q - centre, SC_AXES[f]) / v;
      face = w > 0.0 ? vec4(L, vl_face_code(s, true)) : vec4(0.0, 0.0, 0.0, vl_face_code(s, false));
      hit_a = vec4(pl, float(obj) + 1.0);
      hit_b = vec4(nl, s);
    }
    imageStore(out_image, vl_texel(vl_level, f, t, n), face);
    imageStore(vl_hits, ivec2(12 * id.x + 2 * f, id.y), hit_a);
    imageStore(vl_hits, ivec2(12 * id.x + 2 * f + 1, id.y), hit_b);
  }
}
