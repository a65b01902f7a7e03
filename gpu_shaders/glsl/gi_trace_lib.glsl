/* Lumen GI: the rays of the GI passes (needs sdf_lib.glsl, global_sdf_lib.glsl, surface_cache_lib.glsl).
 *
 * gi_trace: sphere tracing through the mesh SDFs while t < GSDF_MESH_SPLIT (1.8 m, lecture 21),
 * the global SDF beyond. Thin walls: a hit is any point within GI_HIT_VOXELS = 0.5 voxel of the
 * SDF surface. A wall thinner than a voxel never has negative samples, but trilinear filtering
 * of its samples stays below half a voxel on the wall (for samples a fraction f of a voxel from
 * it: 2 f (1 - f) <= 0.5), so no ray passes it: the lecture's "expand the surface by half a voxel",
 * done at trace time for every mesh, over-occluding by that half voxel instead of leaking.
 * A global-SDF hit is refined with the mesh SDFs over the last 1.5 global voxels (to land on a
 * mesh, whose surface cache is then read); if no mesh is found there the global trace goes on.
 * gi_radiance: the surface cache's final light at the hit (sc_sample_world), gi_sky on a miss.
 */
#define GI_HIT_VOXELS 0.5
#define GI_MESH_STEPS 96
#define GI_GLOBAL_STEPS 96
#define GI_REFINE_STEPS 24

bool gi_trace_mesh(vec3 o, vec3 dir, float t0, float t1, out float t, out int obj)
{
  t = t0;
  obj = -1;
  for (int i = 0; i < GI_MESH_STEPS; i++) {
    float h;
    int nearest;
    float d = sdf_scene(o + t * dir, h, nearest);
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

bool gi_trace(vec3 o, vec3 dir, float tmax, out float t, out int obj)
{
  float split = min(GSDF_MESH_SPLIT, tmax);
  if (gi_trace_mesh(o, dir, 0.0, split, t, obj)) {
    return true;
  }
  t = split;
  for (int i = 0; i < GI_GLOBAL_STEPS && t < tmax; i++) {
    int level;
    float v;
    float d = global_sdf_sample(o + t * dir, level, v);
    if (level < 0) {
      return false;               /* left the coarsest clipmap: the sky */
    }
    if (d <= GI_HIT_VOXELS * v) {
      float tr;
      if (gi_trace_mesh(o, dir, max(t - 1.5 * v, 0.0), t + 1.5 * v, tr, obj)) {
        t = tr;
        return true;
      }
      t += 0.5 * v;
      continue;
    }
    t += max(d, 0.1 * v);
  }
  return false;
}

/* World voxel edge of object obj (the unit of ray offsets off its surface). */
float gi_object_voxel(int obj)
{
  return sdf_object_texel(obj, 4).w * sdf_object_texel(obj, 7).w;
}

/* Radiance arriving at o from direction dir: the surface cache at the first hit, sky on a miss.
 * hit_t: the hit distance (tmax on a miss); weight: card weight (0 when no card saw the hit). */
vec3 gi_radiance(vec3 o, vec3 dir, float tmax, vec3 sky, out float hit_t, out float weight)
{
  int obj;
  if (gi_trace(o, dir, tmax, hit_t, obj)) {
    return sc_sample_world(obj, o + hit_t * dir, weight);
  }
  hit_t = tmax;
  weight = 1.0;
  return sky;
}
