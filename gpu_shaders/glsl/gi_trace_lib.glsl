#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "global_sdf_lib.glsl"
#include "surface_cache_lib.glsl"
#include "sky_lib.glsl"
#include "voxel_lighting_lib.glsl"
#include "voxel_lighting_trace_lib.glsl"
/* Lumen GI: the rays of the GI passes (needs sdf_lib.glsl, sdf_ray_lib.glsl,
 * global_sdf_lib.glsl, voxel_lighting_layout_lib.glsl, voxel_lighting_lib.glsl,
 * surface_cache_lib.glsl, sky_lib.glsl).
 *
 * gi_trace: sphere tracing through the mesh SDFs while t < GSDF_MESH_SPLIT (1.8 m, lecture 21),
 * the global SDF beyond, both with the thin-wall rule (sdf_ray_lib.glsl).
 * A global-SDF hit is found on the mesh SDFs over the last 1.5 global voxels (the global SDF's
 * voxels are coarser than a thin wall, which its trace may step past); with voxel lighting bound
 * (voxel_lighting_lib.glsl) only the objects of the hit's 4x4x4-voxel tile are searched (fewer
 * than 32; a full list means more may be near: then all), and the light is read from the voxel
 * lighting there, so the cost no longer grows with the number of objects (before, every object
 * was sampled at every step of that search, and the surface cache's lookup with its thin-wall
 * guard looped over them again). A hit no voxel face serves reads the surface cache as a near hit
 * does. Without voxel lighting every object is searched. If no mesh is found the global trace
 * goes on.
 * gi_radiance(_from): the light at the hit (the surface cache's final light on a mesh hit, the voxel
 * lighting on a served global hit or on an object without cards), sky_ray on a miss.
 */
#define GI_GLOBAL_STEPS 96

/* Half the largest mesh voxel of the scene (world metres), computed on the CPU from the object
 * table (GlobalSDF.params: gsdf.band.y; a loop over every object per ray before). The global SDF
 * holds the mesh SDFs' values, which over a wall thinner than a voxel stay up to half a mesh voxel
 * above zero, and its own trilinear filter adds up to half a global voxel: its hit test allows
 * for both. */
float gi_thin_margin()
{
  return gsdf.band.y;
}

/* World normal of mesh obj's surface at its hit q (the field's gradient over half a voxel). */
vec3 gi_hit_normal(int obj, vec3 q)
{
  float h = sdf_object_texel(obj, 4).w;
  vec3 nl = sdf_mesh_normal_local(obj, sdf_world_to_local(obj, q), 0.5 * h);
  return normalize(transpose(mat3(sc_object_w2l(obj))) * nl);
}

/* obj >= 0: a hit at t on mesh obj; obj = -1: a hit at t served by voxel lighting, whose
 * radiance is voxel_L: a global-SDF hit, or a near hit on an object the bake gave no cards
 * (smaller than Min Card Size: bake.too_small_for_cards; the voxels hold the light around it).
 * mesh: the hit's mesh either way (-1 on a miss).
 * The ray is traced from t_start (> 0 where something else, the screen trace, has shown
 * [0, t_start] empty): on the mesh SDFs up to GSDF_MESH_SPLIT, then on the global SDF, whose
 * mesh searches look no farther back than search_from (a ray going on past a cut-out it hit
 * must not find that cut-out again). */
bool gi_trace_lit_search(vec3 o, vec3 dir, float t_start, float search_from, float tmax,
                         out float t, out int obj, out int mesh, out vec3 voxel_L)
{
  voxel_L = vec3(0.0);
  obj = -1;
  mesh = -1;
  /* Every hit is a mesh hit (a global-SDF sample near a surface only starts a search on the
   * mesh SDFs), and a mesh hit needs sdf_scene <= GI_HIT_VOXELS h <= M / 8 (M: the object grid's
   * margin, at least 4 voxels of the coarsest object; sdf_scene is at least the distance to
   * the grid's box): so the ray ends where it leaves that box grown by M / 8. Only the backward
   * half of a search from a global sample past that point is lost (bench/f12_ab.py: max
   * |Combined| change 0.012 on yard, 0 on cornell; surface-cache rays 0.71x on thin). */
  vec2 span = sdf_scene_box_span(o, dir, 0.125 * sdf_grid_texel(2).x);
  tmax = min(tmax, span.y);
  t = tmax;
  if (span.x > span.y || t_start >= tmax) {
    return false;
  }
  float split = min(GSDF_MESH_SPLIT, tmax);
  /* a hit served by voxel lighting (one vl_sample call site below: a second inlined copy made
   * the passes that trace 8-10% slower): a global hit, or a near hit on an object without cards */
  int vl_level = -1;
  bool hit = false;
  if (t_start < split && gi_trace_mesh(o, dir, t_start, split, t, obj)) {
    mesh = obj;
    if (sc_instance_range(obj).y > 0) {
      return true;
    }
    float v;
    global_sdf_sample(o + t * dir, vl_level, v);
    hit = true;
  }
  if (!hit) {
    t = max(split, t_start);
  }
  float thin = gi_thin_margin();
  /* How far the mesh search has shown the ray empty. A search that finds nothing moves the ray
   * to the end of its window, and the next one starts where it stopped: a ray grazing a floor
   * stays within the global hit test for metres, and searching each stretch again (windows of
   * 3 voxels moved by half a voxel: six times) was most of the global trace's cost
   * (bench/f12_ab.py, 128 px: surface_cache_probe_trace 0.67-0.87x, screen_probe_trace
   * 0.49-0.96x). Nothing is skipped: a tile lists every object whose bounding sphere comes
   * within 1.5 of its voxels, so the search around a point in it covers its whole window; only
   * where a window now starts inside a surface's shell does the hit land a little differently
   * (gi_trace_mesh hits at once there; largest image change 0.02, glow). */
  float searched = search_from;
  for (int i = 0; i < GI_GLOBAL_STEPS && t < tmax && !hit; i++) {
    int level;
    float v;
    float d = global_sdf_sample(o + t * dir, level, v);
    if (level < 0) {
      return false;               /* left the coarsest clipmap: the sky */
    }
    if (d <= GI_HIT_VOXELS * v + thin) {
      /* Find the mesh over the last 1.5 global voxels (the global trace may step past a wall
       * thinner than its voxels): with voxel lighting bound, through the objects of the hit's
       * voxel-lighting tile only, a bounded cost; else through every object. */
      float t0 = max(t - 1.5 * v, searched);
      float t1 = t + 1.5 * v;
      float tr;
      bool found = vl_load_tile(level, o + t * dir) ? vl_trace_tile(o, dir, t0, t1, tr, obj)
                                                     : gi_trace_mesh(o, dir, t0, t1, tr, obj);
      if (found) {
        t = tr;
        vl_level = level;
        hit = true;
        break;
      }
      t = t1;
      searched = t1;
      continue;
    }
    t += max(d - thin, 0.1 * v);
  }
  if (!hit) {
    return false;
  }
  mesh = obj;
  vec3 q = o + t * dir;
  if (vl_level >= 0 && vl_sample(vl_level, q, dir, gi_hit_normal(obj, q), voxel_L)) {
    obj = -1;                     /* served: no surface-cache lookup on the mesh */
  }
  return true;
}

/* obj >= 0: a hit at t on mesh obj; obj = -1: a hit at t served by voxel lighting, whose
 * radiance is voxel_L: a global-SDF hit, or a near hit on an object without cards. */
bool gi_trace_lit_from(vec3 o, vec3 dir, float t_start, float tmax, out float t, out int obj,
                       out vec3 voxel_L)
{
  int mesh;
  return gi_trace_lit_search(o, dir, t_start, 0.0, tmax, t, obj, mesh, voxel_L);
}

bool gi_trace_lit(vec3 o, vec3 dir, float tmax, out float t, out int obj, out vec3 voxel_L)
{
  return gi_trace_lit_from(o, dir, 0.0, tmax, t, obj, voxel_L);
}

/* The hit alone (obj -1: served by voxel lighting). */
bool gi_trace(vec3 o, vec3 dir, float tmax, out float t, out int obj)
{
  vec3 voxel_L;
  return gi_trace_lit(o, dir, tmax, t, obj, voxel_L);
}

/* Cut-outs a GI ray goes on through: past the last, its light is taken as the rest's */
#define GI_CUT_LAYERS 4

/* Where the ray o + t dir leaves the hit shell of mesh `mesh` it entered at t (a cut-out's: its
 * own field, marched until it is clear of the hit rule of sdf_ray_lib.glsl). */
float gi_cut_exit(int mesh, vec3 o, vec3 dir, float t)
{
  float scale = sdf_object_texel(mesh, 7).w;
  float h = sdf_object_texel(mesh, 4).w * scale;
  for (int i = 0; i < 16; i++) {
    float d = sdf_mesh_local(mesh, sdf_world_to_local(mesh, o + t * dir)) * scale;
    if (d > GI_HIT_VOXELS * h) {
      break;
    }
    t += max(GI_HIT_VOXELS * h - d, 0.25 * h);
  }
  return t + 0.05 * h;
}

/* Radiance arriving at o from direction dir: the surface cache (or the voxel lighting) at the
 * first hit, sky on a miss. hit_t: the hit distance (tmax on a miss); weight: card weight (0 when
 * no card saw the hit; 1 on a voxel-lit hit).
 * With GI_CUT_OUTS (compute.VARIANTS: a scene that has a cut-out), a cut-out's hit (object
 * table texel 9 z: the share of its area that is holes, scene_state.py) passes that share of the
 * light from beyond it: the ray goes on from where it leaves the
 * cut-out's shell, up to GI_CUT_LAYERS of them (the sky under a tree's leaves; without, the
 * leaves' cards stood for all of it, and their albedo is weighed by the alpha). An object
 * diffuse rays do not see has share 1 (operators/extract.py shadow_pass). hit_t and weight are
 * the first seen hit's. */
vec3 gi_radiance_from(vec3 o, vec3 dir, float t_start, float tmax, out float hit_t,
                      out float weight)
{
#ifdef GI_CUT_OUTS
  vec3 L = vec3(0.0);
  float carry = 1.0;
  float ts = t_start;
  float search_from = 0.0;
  hit_t = tmax;
  weight = 1.0;
  /* a bound the compiler cannot know (it is GI_CUT_LAYERS): unrolled, the four copies of the
   * trace made the probe passes' first dispatch 3 s slower on llvmpipe (bench/frame_time.py) */
  int layers = GI_CUT_LAYERS + min(sdf_object_count(), 0);
  for (int layer = 0; layer < layers; layer++) {
    int obj, mesh;
    float t, w = 1.0;
    vec3 voxel_L;
    if (!gi_trace_lit_search(o, dir, ts, search_from, tmax, t, obj, mesh, voxel_L)) {
      return L + carry * sky_ray(dir);
    }
    float share = sdf_object_texel(mesh, 9).z;
    /* share 1: an object diffuse rays do not see (Ray Visibility > Diffuse off): neither read
     * nor the ray's hit */
    vec3 Lh = vec3(0.0);
    if (share < 1.0) {
      /* 0: an object without cards no voxel serves */
      Lh = obj < 0 ? voxel_L : sc_sample_world(obj, o + t * dir, dir, w);
      if (hit_t >= tmax) {
        hit_t = t;
        weight = w;
      }
    }
    if (share <= 0.0 || layer == layers - 1) {
      return L + carry * (share < 1.0 ? Lh : sky_ray(dir));
    }
    L += carry * (1.0 - share) * Lh;
    carry *= share;
    ts = gi_cut_exit(mesh, o, dir, t);
    search_from = ts;
    if (ts >= tmax) {
      return L + carry * sky_ray(dir);
    }
  }
  return L;
#else
  int obj, mesh;
  vec3 voxel_L;
  if (gi_trace_lit_search(o, dir, t_start, 0.0, tmax, hit_t, obj, mesh, voxel_L)) {
    if (obj < 0) {
      weight = 1.0;
      return voxel_L;
    }
    return sc_sample_world(obj, o + hit_t * dir, dir, weight);   /* 0: an object without cards
                                                                     * no voxel serves */
  }
  hit_t = tmax;
  weight = 1.0;
  return sky_ray(dir);
#endif
}

vec3 gi_radiance(vec3 o, vec3 dir, float tmax, out float hit_t, out float weight)
{
  return gi_radiance_from(o, dir, 0.0, tmax, hit_t, weight);
}

