/* Lumen GI: the rays of the GI passes (needs sdf_lib.glsl, sdf_ray_lib.glsl,
 * global_sdf_lib.glsl, surface_cache_lib.glsl, sky_lib.glsl).
 *
 * gi_trace: sphere tracing through the mesh SDFs while t < GSDF_MESH_SPLIT (1.8 m, lecture 21),
 * the global SDF beyond, both with the thin-wall rule (sdf_ray_lib.glsl).
 * A global-SDF hit is refined with the mesh SDFs over the last 1.5 global voxels (to land on a
 * mesh, whose surface cache is then read); if no mesh is found there the global trace goes on.
 * gi_radiance: the surface cache's final light at the hit (sc_sample_world), sky_ray on a miss.
 */
#define GI_GLOBAL_STEPS 96

/* Half the largest mesh voxel of the scene (world metres). The global SDF holds the mesh SDFs'
 * values, which over a wall thinner than a voxel stay up to half a mesh voxel above zero, and its
 * own trilinear filter adds up to half a global voxel: its hit test allows for both. */
float gi_thin_margin()
{
  float m = 0.0;
  int n = sdf_object_count();
  for (int i = 0; i < n; i++) {
    m = max(m, sdf_object_texel(i, 4).w * sdf_object_texel(i, 7).w);
  }
  return 0.5 * m;
}

bool gi_trace(vec3 o, vec3 dir, float tmax, out float t, out int obj)
{
  float split = min(GSDF_MESH_SPLIT, tmax);
  if (gi_trace_mesh(o, dir, 0.0, split, t, obj)) {
    return true;
  }
  t = split;
  float thin = gi_thin_margin();
  for (int i = 0; i < GI_GLOBAL_STEPS && t < tmax; i++) {
    int level;
    float v;
    float d = global_sdf_sample(o + t * dir, level, v);
    if (level < 0) {
      return false;               /* left the coarsest clipmap: the sky */
    }
    if (d <= GI_HIT_VOXELS * v + thin) {
      float tr;
      if (gi_trace_mesh(o, dir, max(t - 1.5 * v, 0.0), t + 1.5 * v, tr, obj)) {
        t = tr;
        return true;
      }
      t += 0.5 * v;
      continue;
    }
    t += max(d - thin, 0.1 * v);
  }
  return false;
}

/* Radiance arriving at o from direction dir: the surface cache at the first hit, sky on a miss.
 * hit_t: the hit distance (tmax on a miss); weight: card weight (0 when no card saw the hit). */
vec3 gi_radiance(vec3 o, vec3 dir, float tmax, out float hit_t, out float weight)
{
  int obj;
  if (gi_trace(o, dir, tmax, hit_t, obj)) {
    return sc_sample_world(obj, o + hit_t * dir, dir, weight);
  }
  hit_t = tmax;
  weight = 1.0;
  return sky_ray(dir);
}

