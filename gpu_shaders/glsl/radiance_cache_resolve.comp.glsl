#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "gi_trace_lib.glsl"
#include "radiance_cache_layout_lib.glsl"
#include "radiance_cache_lib.glsl"
#include "screen_probe_ray_lib.glsl"
/* Radiance cache, per screen-probe texel: a ray that screen_probe_trace stopped at
 * rc_trace_distance without a hit (alpha -2) takes its far field from the cache (rc_lookup: 8
 * probes, sphere parallax, visibility); where no probe serves it, it traces on from there to
 * t_max as it did without the cache (so the sky and far walls stay right). In place on
 * probe_radiance_io; alpha becomes t_max + 1 for cache texels (far: the spatial filter shares them; tests count them).
 * Samplers probe_info, probe_normal, probe_rays (the slots' directions), rc_cells, rc_slots, rc_state, rc_atlas (+ the tracer's).
 */
void main()
{
  ivec2 tx = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(probe_radiance_io);
  if (tx.x >= size.x || tx.y >= size.y) {
    return;
  }
  vec4 v = imageLoad(probe_radiance_io, tx);
  if (v.a != -2.0) {
    return;
  }
  ivec2 pr = tx / probe_res;
  ivec2 texel = tx - pr * probe_res;
  vec4 info = texelFetch(probe_info, pr, 0);
  vec3 n = texelFetch(probe_normal, pr, 0).xyz;
  vec3 dir = screen_probe_ray_dir(tx, probe_res, ray_jitter);
  float h;
  int obj;
  sdf_scene(info.xyz, h, obj);
  vec3 o = info.xyz + n * max(gi_object_voxel(max(obj, 0)), 1e-3);
  int k = rc_level(o);
  vec3 L;
  if (rc_lookup(o, dir, k, L)) {
    imageStore(probe_radiance_io, tx, vec4(L, t_max + 1.0));
    return;
  }
  float T = rc_trace_distance(k);
  float t, w;
  L = gi_radiance(o + T * dir, dir, max(t_max - T, 0.0), t, w);
  imageStore(probe_radiance_io, tx, vec4(L, T + t));
}
