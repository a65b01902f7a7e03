#include "gi_trace_lib.glsl"
#include "radiance_cache_layout_lib.glsl"
#include "radiance_cache_lib.glsl"
/* Lumen GI: rc_radiance, a whole screen-probe ray: a short gi_radiance trace, then the world
 * radiance cache (split from radiance_cache_lib.glsl, whose lookup needs no tracer). */
/* gi_radiance with the cache: trace rc_trace_distance, then the cache; where no probe serves
 * the ray, on to tmax. k: the cache level of o (-1: none, an ordinary ray). status: 0 a hit
 * within the short distance or no cache, 1 served by the cache (hit_t = tmax + 1), 2 traced on. */
vec3 rc_radiance(vec3 o, vec3 dir, float tmax, int k, out float hit_t, out int status)
{
  float w;
  status = 0;
  if (k < 0) {
    return gi_radiance(o, dir, tmax, hit_t, w);
  }
  float T = min(rc_trace_distance(k), tmax);
  vec3 L = gi_radiance(o, dir, T, hit_t, w);
  if (hit_t < T || T >= tmax) {
    return L;
  }
  if (rc_lookup(o, dir, k, L)) {
    status = 1;
    hit_t = tmax + 1.0;
    return L;
  }
  status = 2;
  float t;
  L = gi_radiance(o + T * dir, dir, tmax - T, t, w);
  hit_t = T + t;
  return L;
}
