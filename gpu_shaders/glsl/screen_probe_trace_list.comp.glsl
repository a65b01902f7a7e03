#include "screen_probe_trace_lib.glsl"
#include "gi_trace_lib.glsl"
/* Screen probes, the rays the screen trace did not resolve (screen_probe_screen_trace and
 * screen_probe_screen_hit list them in ray_list: atlas texel xy, t_free; ray_counter entries):
 * each traced on the SDFs from t_free (gi_trace_lib.glsl), one invocation per listed ray,
 * dispatched over the count read back.
 * Inputs: screen_probe_trace_lib's; images ray_list, ray_counter (read).
 */
void main()
{
  ivec2 lsize = imageSize(ray_list);
  int slot = int(gl_GlobalInvocationID.x);
  if (slot >= imageLoad(ray_counter, ivec2(0, 0)).x || slot >= lsize.x * lsize.y) {
    return;
  }
  vec4 entry = imageLoad(ray_list, ivec2(slot % lsize.x, slot / lsize.x));
  ivec2 tx = ivec2(entry.xy + 0.5);
  vec3 o, dir;
  float tmax;
  int level;
  if (!probe_ray(tx, o, dir, tmax, level)) {
    return;
  }
  float t, w;
  vec3 L = gi_radiance_from(o, dir, entry.z, tmax, t, w);
  probe_ray_store(tx, o, level, tmax, L, t);
}
