#include "sdf_lib.glsl"
#include "sdf_ray_lib.glsl"
#include "radiance_cache_layout_lib.glsl"
#include "radiance_cache_mark_lib.glsl"
#include "screen_probe_ray_lib.glsl"
/* Screen probes: one ray per octahedral texel of every probe (probe_res^2 per probe, the whole
 * sphere in world-space directions so that neighbours' texels match), shared by the passes that
 * trace them: screen_probe_trace (the SDFs alone), and with the screen trace on
 * screen_probe_lumen_trace (the screen, then the SDFs from where it stops vouching), or with the
 * screen colour's hits screen_probe_screen_trace (the screen first), screen_probe_screen_hit and
 * screen_probe_trace_list (the SDFs for the rays the screen did not resolve, compacted).
 * Directions are jittered inside their texel by ray_jitter (the same for every probe of a frame);
 * with importance sampling a slot may trace another texel or a quarter of one
 * (screen_probe_ray_lib.glsl: probe_rays; screen_probe_compose weights the slots).
 * Rays start one voxel of the nearest object off the probe's surface along its normal.
 * With the world radiance cache on (rc_camera.w > 0, radiance_cache_layout_lib.glsl) a ray whose
 * origin lies in a cache level traces only rc_trace_distance (2 m at level 0): without a hit it
 * is flagged (alpha -2, radiance_cache_resolve fills it in) and marks the 8 cache cells around
 * its origin as used this frame (rc_frame), so that their probes are allocated and traced.
 * Inputs: probe_info, probe_normal, probe_rays, probe_list; push constants probe_res,
 * probe_count, ray_jitter, t_max, rc_camera, rc_frame, texel_step, texel_phase, texel_fill;
 * images out_image, rc_marks.
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

/* The atlas texel of this invocation (a dispatch of probe_count x n invocations, n = (probe_res /
 * texel_step)^2 the texels a probe traces per dispatch): texel k = i % n of the live probe
 * i / n of probe_list (screen_probe_list.comp.glsl: the empty slots are not dispatched); false
 * past the list. */
bool probe_texel(out ivec2 tx)
{
  int side = probe_res / texel_step;
  int i = int(gl_GlobalInvocationID.x);
  int e = i / (side * side);
  tx = ivec2(0);
  if (e >= probe_count) {
    return false;
  }
  ivec2 lsize = textureSize(probe_list, 0);
  ivec2 slot = ivec2(texelFetch(probe_list, ivec2(e % lsize.x, e / lsize.x), 0).xy + 0.5);
  int k = i - e * side * side;
  tx = slot * probe_res + ivec2(k % side, k / side) * texel_step + texel_phase;
  return true;
}

/* The ray of atlas texel tx: origin o, direction dir, the distance it traces (tmax) and the
 * radiance-cache level of o (-1: none). False where the slot holds no probe (stored as such). */
bool probe_ray(ivec2 tx, out vec3 o, out vec3 dir, out float tmax, out int level)
{
  vec4 info = texelFetch(probe_info, tx / probe_res, 0);
  o = dir = vec3(0.0);
  tmax = t_max;
  level = -1;
  if (info.w <= 0.0) {
    split_store(tx, vec4(0.0, 0.0, 0.0, -1.0));
    return false;
  }
  vec3 n = texelFetch(probe_normal, tx / probe_res, 0).xyz;
  dir = screen_probe_ray_dir(tx, probe_res, ray_jitter);  /* importance sampling */
  float h;
  int obj;
  sdf_scene(info.xyz, h, obj);
  o = info.xyz + n * max(gi_object_voxel(max(obj, 0)), 1e-3);
  level = rc_level(o);
  tmax = level >= 0 ? min(rc_trace_distance(level), t_max) : t_max;
  return true;
}

/* This invocation's texel and its ray (probe_texel, probe_ray); false: nothing to trace. */
bool probe_begin(out ivec2 tx, out vec3 o, out vec3 dir, out float tmax, out int level)
{
  o = dir = vec3(0.0);
  tmax = t_max;
  level = -1;
  return probe_texel(tx) && probe_ray(tx, o, dir, tmax, level);
}

/* The ray's result (radiance L, hit distance t): a ray cut short for the radiance cache that met
 * nothing is flagged for it and marks its cells. */
void probe_ray_store(ivec2 tx, vec3 o, int level, float tmax, vec3 L, float t)
{
  if (tmax < t_max && t >= tmax) {
    rc_mark(o, level, rc_frame);
    split_store(tx, vec4(0.0, 0.0, 0.0, -2.0));
    return;
  }
  split_store(tx, vec4(L, t));
}
