#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "radiance_cache_layout_lib.glsl"
#include "radiance_cache_mark_lib.glsl"
#include "screen_probe_ray_lib.glsl"
#include "lumen_trace_lib.glsl"
/* Screen probes, tracing: one ray per octahedral texel of every probe (probe_res^2 per probe,
 * the whole sphere in world-space directions so that neighbours' texels match), through
 * lumen_trace_lib.glsl (the screen first if on, mesh SDFs near, global SDF far, the surface
 * cache at hits, sky on a miss).
 * Directions are jittered inside their texel by ray_jitter (the same for every probe of a frame);
 * with importance sampling a slot may trace another texel or a quarter of one
 * (screen_probe_ray_lib.glsl: probe_rays; screen_probe_compose weights the slots).
 * Rays start one voxel of the nearest object off the probe's surface along its normal.
 * With the world radiance cache on (rc_camera.w > 0, radiance_cache_layout_lib.glsl) a ray whose
 * origin lies in a cache level traces only rc_trace_distance (2 m at level 0): without a hit it
 * is flagged (alpha -2, radiance_cache_resolve fills it in) and marks the 8 cache cells around
 * its origin as used this frame (rc_frame), so that their probes are allocated and traced.
 * Inputs: probe_info, probe_normal, probe_rays, screen_trace.SAMPLERS; push constants probe_res,
 * ray_jitter, t_max, rc_camera, rc_frame, screen_trace.PUSH; image rc_marks.
 * Output out_image (probe atlas, probe (i, j) at texels [i*res, (i+1)*res) x [j*res, ...)):
 * radiance rgb, a = hit distance (t_max on a miss, -1 where there is no probe, -2 to resolve).
 */
/* texel_step 2 (the viewport's split, GISettings.split 4): the dispatch covers the atlas / 2 and
 * traces one texel of every 2x2 block (texel_phase); the others keep earlier redraws' rays of the
 * same probe slot (the same screen tile). The ray also goes into those of its block that hold no
 * ray (w -1: the slot had no probe then) and, with texel_fill 1 (the first redraw after a
 * reset), into the whole block: a first frame's probes are whole at a quarter of the rays. */
void split_store(ivec2 tx, vec4 v)
{
  imageStore(out_image, tx, v);
  if (texel_step == 1) {
    return;
  }
  ivec2 b = tx - texel_phase;
  for (int k = 0; k < texel_step * texel_step; k++) {
    ivec2 q = b + ivec2(k % texel_step, k / texel_step);
    if (q != tx && (texel_fill != 0 || imageLoad(out_image, q).w == -1.0)) {
      imageStore(out_image, q, v);
    }
  }
}

void main()
{
  ivec2 tx = ivec2(gl_GlobalInvocationID.xy) * texel_step + texel_phase;
  ivec2 size = imageSize(out_image);
  if (tx.x >= size.x || tx.y >= size.y) {
    return;
  }
  ivec2 pr = tx / probe_res;
  ivec2 texel = tx - pr * probe_res;
  vec4 info = texelFetch(probe_info, pr, 0);
  if (info.w <= 0.0) {
    split_store(tx, vec4(0.0, 0.0, 0.0, -1.0));
    return;
  }
  vec3 n = texelFetch(probe_normal, pr, 0).xyz;
  vec3 dir = screen_probe_ray_dir(tx, probe_res, ray_jitter);  /* importance sampling */
  float h;
  int obj;
  sdf_scene(info.xyz, h, obj);
  vec3 o = info.xyz + n * max(gi_object_voxel(max(obj, 0)), 1e-3);
  int k = rc_level(o);
  float tmax = k >= 0 ? min(rc_trace_distance(k), t_max) : t_max;
  float t;
  int kind;
  vec3 L = lumen_radiance(o, dir, tmax, t, kind);
  if (tmax < t_max && t >= tmax) {
    rc_mark(o, k, rc_frame);
    split_store(tx, vec4(0.0, 0.0, 0.0, -2.0));
    return;
  }
  split_store(tx, vec4(L, t));
}
